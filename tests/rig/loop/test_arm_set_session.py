"""Several arms on the hardware path (rig/loop/arm_set_session.py): the boxes named per arm, each
arm's walk, and one camera frame per cycle shared by every arm's loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.robot_params import RobotParams
from wristmark.rig.loop.arm_clearance import bodies_at, least_distance
from wristmark.rig.loop.arm_set_session import (
    SharedFrameFeed,
    arm_trajectories,
    parse_serial_specs,
    parse_target_specs,
)
from wristmark.rig.loop.scene_file import Scene, pose_from_xyz_rpy
from wristmark.rig.loop.servo_session import PointHold
from wristmark.rig.targets.trajectories import workspace_centre

NAMES = ["a", "b"]


def test_each_arm_gets_its_own_port_in_the_scenes_order() -> None:
    assert list(parse_serial_specs(["b=/dev/pts/7", "a=socket://127.0.0.1:9"], NAMES).items()) == [
        ("a", "socket://127.0.0.1:9"), ("b", "/dev/pts/7")]


@pytest.mark.parametrize(("specs", "cause"), [
    (["a=/dev/pts/1"], "no box for arm 'b'"),
    (["a=/dev/pts/1", "c=/dev/pts/2"], "no arm 'c' in the scene"),
    (["a=/dev/pts/1", "b=/dev/pts/1"], "port /dev/pts/1 given for both 'a' and 'b'"),
    (["a=/dev/pts/1", "a=/dev/pts/2", "b=/dev/pts/3"], "arm 'a' given twice"),
    (["/dev/pts/1", "b=/dev/pts/2"], "each box is NAME=PORT"),
    (["a=", "b=/dev/pts/2"], "each box is NAME=PORT"),
])
def test_bad_serial_specs_are_refused_in_one_line_naming_the_cause(specs: list[str], cause: str) -> None:
    with pytest.raises(InputError) as e:
        parse_serial_specs(specs, NAMES)
    assert cause in str(e.value) and "\n" not in str(e.value)


def test_each_arm_named_gets_its_own_live_target_source() -> None:
    assert parse_target_specs(["b=tcp:127.0.0.1:0", "a=stdin"], NAMES) == {"b": ("tcp", 0), "a": ("stdin", None)}
    assert parse_target_specs(["a=tcp:5000"], NAMES, hold=("b",)) == {"a": ("tcp", 5000)}
    assert parse_target_specs([], NAMES) == {}
    assert parse_target_specs(["a=ros2", "b=tcp:0"], NAMES, ros2=True) == {"a": ("ros2", None), "b": ("tcp", 0)}


@pytest.mark.parametrize(("specs", "hold", "cause"), [
    (["tcp:0"], (), "each arm's targets are NAME=SPEC"),
    (["c=stdin"], (), "no arm 'c' in the scene"),
    (["a=stdin", "a=tcp:0"], (), "arm 'a' given twice"),
    (["a=stdin", "b=stdin"], (), "stdin given for both 'a' and 'b'"),
    (["a=tcp:192.168.1.2:5000"], (), "loopback only"),
    (["a=tcp:127.0.0.1:70000"], (), "PORT must be an integer"),
    (["a=ros2"], (), "--target a=ros2 needs --ros2 [NS]: arm a's targets come from NS/a/servo_cp"),
    (["a=cube"], (), "stdin, tcp:127.0.0.1:PORT or ros2"),
    (["a=spline"], (), "--target must be"),
    (["b=tcp:0"], ("b",), "also in --hold"),
])
def test_bad_target_specs_are_refused_in_one_line_naming_the_cause(specs: list[str], hold: tuple[str, ...],
                                                                   cause: str) -> None:
    with pytest.raises(InputError) as e:
        parse_target_specs(specs, NAMES, hold)
    assert cause in str(e.value) and "\n" not in str(e.value)


def test_each_arm_walks_its_own_cube_or_holds_its_centre() -> None:
    arms = {"a": RobotParams(), "b": RobotParams()}
    size = (0.02, 0.01, 0.02)
    trajs = arm_trajectories(arms, size, "cube", duration=3.0, hold=("b",))
    assert trajs["a"].duration == pytest.approx(3.0)
    assert isinstance(trajs["b"], PointHold) and trajs["b"].duration == pytest.approx(3.0)
    np.testing.assert_allclose(trajs["b"].sample(1.0)[0], workspace_centre(RobotParams(), size))
    assert not np.allclose(trajs["a"].sample(0.0)[0], trajs["a"].sample(2.0)[0])  # a walks
    points = arm_trajectories(arms, size, "point", duration=2.0)
    assert all(isinstance(t, PointHold) and t.duration == pytest.approx(2.0) for t in points.values())
    with pytest.raises(ConfigError, match="no such arm"):
        arm_trajectories(arms, size, hold=("c",))
    with pytest.raises(ConfigError, match="every arm would hold still"):
        arm_trajectories(arms, size, hold=("a", "b"))


def test_the_shipped_scene_reads_without_the_simulated_bench_and_its_arms_start_apart() -> None:
    scene = Scene.load("configs/scenes/two_arms.yaml")
    assert scene.names == NAMES
    np.testing.assert_allclose(scene.arms[1].base, pose_from_xyz_rpy([0.2, 0, 0], [0, 0, math.pi]))
    from wristmark.models.arm_spec import home_psi

    params = {a.name: RobotParams() for a in scene.arms}
    bases = {a.name: a.base for a in scene.arms}
    home = {n: home_psi(p) for n, p in params.items()}
    apart = least_distance(bodies_at(params, home, bases))
    assert apart > 0.02  # two arms facing each other 200 mm apart
    closer = least_distance(bodies_at(params, home, bases, offsets={"a": np.array([0.01, 0.0, 0.0])}))
    assert closer == pytest.approx(apart - 0.01, abs=1e-6)  # a's body shifted 10 mm towards b


class _Feed:
    """A camera feed that hands out a new frame on every take and counts the takes."""

    name = "fake"
    dropped = 0
    received = 0

    def __init__(self) -> None:
        self.takes = 0
        self.last_arrival = math.nan
        self.closed = 0

    def take(self, fresh_after: float = -math.inf, wait_until: float = -math.inf) -> StereoFrame:
        self.takes += 1
        self.last_arrival = float(self.takes)
        img = np.zeros((2, 2), np.uint8)
        return StereoFrame(img, img, float(self.takes), self.takes, "fake", "fake")

    def close(self) -> None:
        self.closed += 1


def test_every_arm_of_a_cycle_gets_the_one_frame_of_that_cycle() -> None:
    inner = _Feed()
    feed = SharedFrameFeed(inner)  # type: ignore[arg-type]
    feed.begin_cycle()
    first = feed.take(wait_until=1.0)
    assert feed.take() is first and feed.take() is first and inner.takes == 1
    assert feed.last_arrival == 1.0
    feed.begin_cycle()
    second = feed.take()
    assert second is not first and second.index == 2 and feed.take() is second and inner.takes == 2
    feed.close()
    feed.close()
    assert inner.closed == 1


@pytest.mark.wallclock
def test_a_probed_arms_link_feeds_the_other_boxes_from_its_own_thread() -> None:
    """While one arm probes its play alone, each time its time runs on (in steps under the 250 ms
    watchdog) or it is commanded, the other boxes get a GET_STATE from the loop's own thread (no
    keep-alive thread whose replies wait behind the loop's work): a box enabled and silent for
    0.6 s trips its watchdog, fed so it does not; an emergency stop on a fed box raises at once,
    naming its arm (not the probed one's)."""
    import threading

    from tests.rig.link.test_serial_link import open_bench
    from wristmark.rig.link import protocol as P
    from wristmark.rig.link.actuator_driver import ActuatorEStopped
    from wristmark.rig.loop.arm_set_session import FeedingLink, on_arm

    probed, kept, alone = (open_bench(simulated=False) for _ in range(3))
    threads: set[str] = set()
    get_state = kept.link.driver.get_state

    def spied() -> object:
        threads.add(threading.current_thread().name)
        return get_state()

    kept.link.driver.get_state = spied  # type: ignore[method-assign]
    try:
        link = FeedingLink(probed.link, {"b": kept.link})
        before = kept.emulator.received.count("GetState")
        t0 = link.time
        link.advance_to(t0 + 0.6)  # one call: the others fed at least every 0.1 s of it
        link.send_target(probed.link.measured_actuators())
        assert link.time >= t0 + 0.6 and link.wrapped is probed.link
        assert not kept.emulator.watchdog_tripped and kept.emulator.enabled
        assert kept.emulator.received.count("GetState") - before >= 7  # 6 steps of 0.1 s, then the command
        assert threads == {threading.current_thread().name}
        assert alone.emulator.watchdog_tripped and not alone.emulator.enabled
        kept.emulator.receive(P.encode(P.EStop(seq=0)))  # the operator's button on b's box
        with pytest.raises(ActuatorEStopped) as stop, on_arm("a"):  # during a's cycles: b's stop, named b's
            link.advance_to(link.time + 0.01)
        assert str(stop.value).startswith("arm 'b': ") and "arm 'a'" not in str(stop.value)
    finally:
        for b in (probed, kept, alone):
            b.link.close()
            b.emulator.stop()
