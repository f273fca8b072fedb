"""Several arms on the hardware path: ``wristmark servo --scene SCENE --serial NAME=PORT ...
--camera SPEC --calib C`` (docs/hardware.md "Several arms"), or ``--actuator NAME=ros2:NS ...``
(each arm a rig.ros2.actuator_link.Ros2ActuatorLink on one shared participant). Nothing here imports the simulated
bench: the scene file is read by :mod:`rig.loop.scene_file`.

One process, one camera, one actuator box per arm (each its own :class:`rig.link.serial_link.SerialLink`,
protocol v1 or v2), each arm its own :class:`rig.loop.servo_loop.ServoLoop`, controller and
trajectory (in its own {w}), all in lockstep on the host's ``time.monotonic()`` clock. Per cycle:
every arm's time runs to the cycle's start (each box polled), the clearance between the arms is
handed to every controller (:mod:`rig.loop.arm_clearance`, as the simulated bench's
``sim.several_arms.walk_scene`` does), then each arm's loop runs its cycle on the one frame of
the cycle (:class:`SharedFrameFeed`) and the one tracking of every sleeve in it
(:class:`BudgetedArmSetSensor`, within the rig's ``tracking_budget``).

Stops: an arm whose marker stays lost (rig ``max_lost_cycles``) is held and disabled alone, the
others walk on; a camera that stalls, a box that stops answering, an emergency stop, a watchdog
trip or Ctrl-C hold and disable every arm. A controller that probes its play (rig/loop/play_probe.py)
probes it one arm at a time after the settle, as the simulated bench does; the other boxes are
polled meanwhile from the probe's own cycles (:class:`FeedingLink`: no second thread touches a
link). No frame phase lock: one grid for every arm.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.cvs.tracking.result import TrackResult
from wristmark.models.actuation import psi_from_actuators
from wristmark.models.arm_spec import Arm
from wristmark.models.errors import ConfigError, InputError, WristmarkError
from wristmark.models.limits import clamp_psi
from wristmark.rig.link.serial_link import KEEPALIVE_S, SerialLink
from wristmark.rig.loop.arm_clearance import bodies_at, least_distance, model_bodies, model_offsets, set_obstacles
from wristmark.rig.loop.arm_set_sensor import ArmSensorView, ArmSetSensor
from wristmark.rig.loop.frame_feed import LatestFrameFeed
from wristmark.rig.loop.loop_setup import LoopSetup, load_loop_setup
from wristmark.rig.loop.play_probe import probe_report
from wristmark.rig.loop.scene_file import Scene
from wristmark.rig.loop.servo_cycle import (
    CameraStalledError,
    MarkerLostError,
    PhaseStats,
    TrackingMemory,
    cycle_target,
    ramp_to,
)
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.loop.servo_session import (
    POINT_HOLD_S,
    LinkOptions,
    PointHold,
    ServoOutcome,
    ServoSession,
    _count,
)
from wristmark.rig.loop.tip_sensors import TipMeasurement, tip_measurement
from wristmark.rig.recording.run_log import RunLog
from wristmark.rig.targets.live_target import parse_target_spec
from wristmark.rig.targets.trajectories import CUBE_SPEED, Trajectory, cube_trajectory, workspace_centre

Array = NDArray[np.float64]
SETTLE_AT_START_S = 2.0  # [s] every arm rests at its start after the ramp there (as ServoLoop.start_at)

__all__ = ["ArmSetSession", "BudgetedArmSetSensor", "SharedFrameFeed", "arm_trajectories", "check_arm_orientation",
           "load_scene_setups",
           "open_arm_set_session", "parse_actuator_specs", "parse_serial_specs", "parse_target_specs", "run_arm_set"]


# -- configuration ---------------------------------------------------------------------------
def load_scene_setups(scene: Scene, calib: str | Path, rig: str | Path | None = None,
                      controller: str | Path | None = None) -> tuple[dict[str, LoopSetup], StereoCamera]:
    """Each arm's LoopSetup (its robot and marker files from the scene, the shared rig and
    controller files; its camera's ``world_T_left`` the scene camera's seen from the arm's base)
    and the scene camera (``calib``: world_T_left in the scene's {w}, required)."""
    from wristmark.cvs.calibration.load import load_calibration

    cam = load_calibration(calib)
    if cam.T_world_left is None:
        raise ConfigError(f"{calib}: several arms need 'world_T_left' (the camera's pose in the scene's {{w}}; "
                          "the virtual lab writes it with --calib-out)")
    W = np.asarray(cam.T_world_left, float)
    setups = {}
    for a in scene.arms:
        s = load_loop_setup(robot=a.robot, marker=a.marker, camera=calib, rig=rig, controller=controller)
        setups[a.name] = s.with_changes(camera=dataclasses.replace(cam, T_world_left=np.linalg.inv(a.base) @ W))
    return setups, cam


def named_specs(option: str, specs: Sequence[str], names: Sequence[str], what: str) -> dict[str, str]:
    """``NAME=VALUE`` of ``option`` -> {arm: value} in the order given; InputError (one line) for a
    malformed spec (``what``: "box is NAME=PORT", say), an unknown arm or an arm given twice."""
    out: dict[str, str] = {}
    for spec in specs:
        name, sep, value = spec.partition("=")
        if not sep or not name or not value:
            raise InputError(f"{option} {spec!r}: with --scene each {what} (arms: {', '.join(names)})")
        if name not in names:
            raise InputError(f"{option} {spec}: no arm '{name}' in the scene (arms: {', '.join(names)})")
        if name in out:
            raise InputError(f"{option}: arm '{name}' given twice")
        out[name] = value
    return out


def parse_serial_specs(specs: Sequence[str], names: Sequence[str]) -> dict[str, str]:
    """``NAME=PORT`` per arm -> {arm: port} in the scene's order; InputError (one line) for a
    malformed spec, an unknown arm, an arm given twice, a port given twice or an arm missing."""
    return one_per_arm("--serial", named_specs("--serial", specs, names, "box is NAME=PORT"), names, "port",
                       "box", "PORT")


def one_per_arm(option: str, given: Mapping[str, str], names: Sequence[str], what: str, thing: str, form: str
                ) -> dict[str, str]:
    """``given`` ({arm: port or namespace}) in the scene's order; InputError (one line) for a value
    given for two arms or an arm without one (``thing``: what each arm needs, ``form``: its spec)."""
    seen: dict[str, str] = {}
    for name, value in given.items():
        if value in seen:
            raise InputError(f"{option}: {what} {value} given for both '{seen[value]}' and '{name}'")
        seen[value] = name
    missing = [n for n in names if n not in given]
    if missing:
        raise InputError(f"{option}: no {thing} for arm '{missing[0]}' (give {option} {missing[0]}={form} for each "
                         f"of {', '.join(names)})")
    return {n: given[n] for n in names}


def parse_actuator_specs(specs: Sequence[str], names: Sequence[str]) -> dict[str, str]:
    """``NAME=ros2:NS`` per arm (``--actuator``: the arm's driver on a ROS 2 graph) -> {arm:
    namespace} in the scene's order; InputError (one line) for a malformed spec or namespace, an
    unknown arm, an arm given twice, a namespace given twice or an arm missing."""
    from wristmark.rig.ros2.bridge import clean_namespace

    out: dict[str, str] = {}
    for name, value in named_specs("--actuator", specs, names, "arm is NAME=ros2:NS").items():
        if not value.startswith("ros2:"):
            raise InputError(f"--actuator {name}={value}: with --scene each arm is NAME=ros2:NS (an arm on a ROS 2 "
                             "graph; serial boxes are --serial NAME=PORT)")
        try:
            out[name] = clean_namespace(value[len("ros2:"):] or "-")
        except ValueError as e:
            raise InputError(f"--actuator {name}={value}: {e}") from None
    return one_per_arm("--actuator", out, names, "namespace", "arm driver", "ros2:NS")


def parse_target_specs(specs: Sequence[str], names: Sequence[str], hold: Sequence[str] = (), ros2: bool = False
                       ) -> dict[str, tuple[str, int | None]]:
    """``--target NAME=SPEC`` -> {arm: (kind, TCP port)}, kind stdin (one arm at most), tcp
    (``tcp:127.0.0.1:PORT``, loopback only; PORT 0: any free port) or ros2 (``NS/NAME/servo_cp``,
    only with ``ros2``: the scene on a ROS 2 graph); InputError (one line) for a bad spec, an
    unknown arm, an arm given twice or also held, stdin for two arms, ros2 without ``ros2``."""
    out: dict[str, tuple[str, int | None]] = {}
    for name, spec in named_specs("--target", specs, names, "arm's targets are NAME=SPEC").items():
        kind, _, port = parse_target_spec(spec)
        if kind not in ("stdin", "tcp", "ros2"):
            raise InputError(f"--target {name}={spec}: with --scene an arm's targets come from stdin, "
                             "tcp:127.0.0.1:PORT or ros2 (the others walk --trajectory or --hold)")
        if kind == "ros2" and not ros2:
            raise InputError(f"--target {name}=ros2 needs --ros2 [NS]: arm {name}'s targets come from "
                             f"NS/{name}/servo_cp")
        if kind == "stdin" and any(k == "stdin" for k, _ in out.values()):
            other = next(n for n, (k, _) in out.items() if k == "stdin")
            raise InputError(f"--target: stdin given for both '{other}' and '{name}' (one arm at most)")
        if name in hold:
            raise InputError(f"--target {name}={spec}: arm '{name}' is also in --hold (one or the other)")
        out[name] = (kind, port)
    return out


def check_arm_orientation(mode: str, controller_kinds: Mapping[str, str]) -> str:
    """``mode`` (none | hold | follow) if every arm's controller can control it; ConfigError naming
    the first arm whose controller cannot (the paper's is position-only)."""
    from wristmark.rig.targets.orientation_path import check_orientation_mode

    for n, kind in controller_kinds.items():
        try:
            check_orientation_mode(mode, kind)
        except ConfigError as e:
            raise ConfigError(f"arm '{n}': {e}") from None
    return mode


def arm_trajectories(params: Mapping[str, Arm], cube_size: tuple[float, float, float], kind: str = "cube",
                     duration: float | None = None, hold: Sequence[str] = (),
                     orientation: str = "none") -> dict[str, Trajectory]:
    """Each arm's cube (``cube_size`` [m] around its workspace centre, at the paper's speed) or,
    for ``kind`` point, its workspace centre held (``duration``, default POINT_HOLD_S), in its own
    {w}; the arms in ``hold`` hold their centre as long as the others walk. ``duration`` [s]
    cuts the walks short; ``orientation`` (none | hold | follow, rig.targets.orientation_path):
    the tip frame's orientation each path asks for, from its own arm (check the controllers with
    :func:`check_arm_orientation`). ConfigError for an unknown arm in ``hold`` or every arm held."""
    names = list(params)
    unknown = [h for h in hold if h not in params]
    if unknown:
        raise ConfigError(f"--hold {unknown[0]}: no such arm in the scene ({', '.join(names)})")
    if len(set(hold)) == len(names):
        raise ConfigError("--hold: every arm would hold still; leave at least one to walk its cube")
    centres = {n: workspace_centre(p, cube_size) for n, p in params.items()}
    out: dict[str, Trajectory] = {}
    if kind == "point":
        length = duration if duration is not None else POINT_HOLD_S
        out = {n: PointHold(np.array([c]), 1.0, hold=length) for n, c in centres.items()}
    else:
        cubes = {n: cube_trajectory(c, cube_size, CUBE_SPEED) for n, c in centres.items()}
        if duration is not None:
            cubes = {n: c.truncated(duration) for n, c in cubes.items()}
        longest = max(c.duration for c in cubes.values())
        for n in names:
            out[n] = PointHold(np.array([centres[n]]), 1.0, hold=longest) if n in hold else cubes[n]
    if orientation != "none":
        out = {n: t.with_orientation(orientation, params[n]) for n, t in out.items()}
    return out


# -- one frame, one tracking, for every arm ----------------------------------------------------
class SharedFrameFeed:
    """One camera's :class:`rig.loop.frame_feed.LatestFrameFeed` shared by several arms' loops
    stepping in lockstep: the first :meth:`take` after :meth:`begin_cycle` takes from the camera
    (waiting as the loop asks), every other take of that cycle gets the same frame (or None)."""

    def __init__(self, feed: LatestFrameFeed) -> None:
        self.feed = feed
        self.name = feed.name
        self._cycle = 0
        self._taken = -1
        self._frame: StereoFrame | None = None
        self._closed = False
        self._solo = False
        self.last_arrival = feed.last_arrival  # when the last frame taken arrived (time.monotonic() [s])

    def begin_cycle(self) -> None:
        """A new cycle: the next take reads the camera."""
        self._cycle += 1

    @contextmanager
    def solo(self) -> Iterator[None]:
        """While one arm's loop runs cycles of its own (its play probe): every take reads the camera."""
        self._solo = True
        try:
            yield
        finally:
            self._solo = False

    def take(self, fresh_after: float = -np.inf, wait_until: float = -np.inf) -> StereoFrame | None:
        """This cycle's frame (see the class docstring); the camera's error propagates."""
        if self._taken != self._cycle or self._solo:
            self._frame = self.feed.take(fresh_after=fresh_after, wait_until=wait_until)
            self._taken = self._cycle
            self.last_arrival = self.feed.last_arrival
        return self._frame

    @property
    def dropped(self) -> int:
        """Frames dropped (the camera's feed)."""
        return self.feed.dropped

    @property
    def received(self) -> int:
        """Frames received from the camera."""
        return self.feed.received

    def close(self) -> None:
        """Close the camera (once)."""
        if not self._closed:
            self._closed = True
            self.feed.close()


class BudgetedArmSetSensor(ArmSetSensor):
    """An :class:`rig.loop.arm_set_sensor.ArmSetSensor` whose tracking of a frame (every sleeve at
    once) runs in a worker thread and is given up after ``budget`` [s] for every arm of that
    frame (as :class:`rig.loop.tip_sensors.DeadlineTipSensor` does for one arm: no cycle outlasts
    the boxes' watchdog); a frame that comes while the worker is busy is not measured. A missing
    arm's whole-frame search runs beside the other arms' tracking, not in their cycles
    (``ArmSetTracker(background_search=True)``)."""

    def __init__(self, camera: StereoCamera, markers: Sequence[Any], budget: float, magnify: float = 1.0,
                 processes: bool = False) -> None:
        from concurrent.futures import ThreadPoolExecutor

        super().__init__(camera, markers, magnify=magnify, processes=processes, background_search=True)
        if not budget > 0:
            raise ValueError(f"budget must be > 0 s, got {budget}")
        self.budget = float(budget)
        self.late = 0
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="arm-set-sensor")
        self._busy: Any = None
        self._given_up: tuple[int, str] | None = None  # (frame index, why) of a frame given up

    def within_budget(self, frame: StereoFrame) -> dict[str, TrackResult] | str:
        """Every arm's result for ``frame``, or why there is none (over the budget, busy)."""
        from concurrent.futures import TimeoutError

        if frame is self._frame and frame.index == self._frame_index:
            return self._results
        if self._given_up is not None and self._given_up[0] == frame.index:
            return self._given_up[1]
        if self._busy is not None and not self._busy.done():
            why = "tracker still busy with an earlier frame"
        else:
            self._busy = self._pool.submit(self.results, frame)
            try:
                return dict(self._busy.result(timeout=self.budget))
            except TimeoutError:
                self.late += 1
                why = f"tracking took longer than {1000 * self.budget:.0f} ms"
        self._given_up = (frame.index, why)
        return why

    def view(self, arm: str, T_world_left: Array) -> ArmSensorView:
        """Arm ``arm``'s tip sensor in its own {w} (see :class:`ArmSensorView`), within the budget."""
        if arm not in self.tracker.arms:
            raise KeyError(f"no arm '{arm}' in the marker set ({', '.join(self.tracker.arms)})")
        return _BudgetedView(self, arm, np.asarray(T_world_left, float))

    def close(self) -> None:
        """Let a running tracking finish and stop the worker (and the tracker's worker processes)."""
        self._pool.shutdown(wait=True)
        super().close()


class _BudgetedView(ArmSensorView):
    """One arm's share of a :class:`BudgetedArmSetSensor`."""

    shared: BudgetedArmSetSensor

    def measure(self, frame: StereoFrame, axis_hint_world: Array | None = None) -> TipMeasurement:
        """This arm's tip in its {w}, or a failed measurement when the frame's tracking was given up."""
        self.last_frame = frame
        if axis_hint_world is not None:
            self.shared.hints[self.arm] = self.T_world_left[:3, :3].T @ np.asarray(axis_hint_world, float)
        got = self.shared.within_budget(frame)
        if isinstance(got, str):
            return TipMeasurement(False, None, got, 1000.0 * self.shared.budget, t_capture=frame.t_capture,
                                  frame_index=frame.index)
        return tip_measurement(got[self.arm], frame, self.shared.last_ms, self.T_world_left)


@contextmanager
def on_arm(name: str) -> Iterator[None]:
    """An actuator box's error raised again naming its arm (the same type: the stop's cause); one
    that names its arm already (another box's, fed from this arm's cycles) passes unchanged."""
    from wristmark.rig.link.actuator_driver import ActuatorError

    try:
        yield
    except ActuatorError as e:
        if getattr(e, "arm", None) is not None:
            raise
        named = type(e)(f"arm '{name}': {e}")
        named.arm = name  # type: ignore[attr-defined]
        raise named from None


class FeedingLink:
    """Arm ``name``'s link while its loop runs cycles alone (its play probe), feeding the other
    boxes (``others``, by arm) from the same thread: whenever the probed arm's box is talked to
    (its time run on, in steps of at most ``keepalive_s``; a command; an encoder reading; a hold),
    every other box gets a GET_STATE right after, checked as a cycle's poll is (an emergency stop,
    a fault or a watchdog trip raises at once, naming its arm). So no other box is ever silent
    longer than the probed arm's own (skipping boxes fed a few ms ago made them so: the probe's
    last fits are ~200 ms without an exchange under load, and a box fed 40 ms before them
    tripped its watchdog), and no second thread touches a link or waits for a reply behind the
    loop's work (a keep-alive thread did: under load its replies were read late, and a box was
    reported "not answering")."""

    def __init__(self, link: Any, others: Mapping[str, Any], keepalive_s: float = KEEPALIVE_S) -> None:
        self.link = link
        self.others = dict(others)
        self.keepalive_s = float(keepalive_s)

    @property
    def wrapped(self) -> Any:
        """The probed arm's own link (rig.link.actuator_link.box_actuators)."""
        return self.link

    @property
    def time(self) -> float:
        """The probed arm's link's time [s]."""
        return float(self.link.time)

    def feed(self) -> None:
        """One GET_STATE to every other box, checked (its time run on to now: no wait)."""
        for name, other in self.others.items():
            with on_arm(name):
                other.advance_to(other.time)

    def advance_to(self, t: float) -> None:
        """Let time run to ``t`` [s] in steps of at most ``keepalive_s``, the others fed after each."""
        while True:
            step = min(t, self.link.time + self.keepalive_s)
            self.link.advance_to(step)
            self.feed()
            if step >= t:
                return

    def send_target(self, actuators: Array) -> None:
        """Command the probed arm, then feed the others."""
        self.link.send_target(actuators)
        self.feed()

    def hold(self) -> None:
        """Hold the probed arm, then feed the others."""
        self.link.hold()
        self.feed()

    def measured_actuators(self) -> Array:
        """The probed arm's encoders, then the others fed."""
        out = np.asarray(self.link.measured_actuators(), float)
        self.feed()
        return out

    def close(self) -> None:
        """Close the probed arm's link."""
        self.link.close()


@contextmanager
def feeding_others(loop: ServoLoop, others: Mapping[str, Any]) -> Iterator[FeedingLink]:
    """While the block runs ``loop`` alone, its link is a :class:`FeedingLink` feeding ``others``."""
    own = loop.link
    feeding = FeedingLink(own, others)
    loop.link = feeding
    try:
        yield feeding
    finally:
        loop.link = own


# -- the session --------------------------------------------------------------------------------
@dataclass
class ArmSetSession:
    """Every arm's open box (``links``, by arm in the scene's order, with their ``ports``: a
    SerialLink each, or with ``options.kind`` ros2 a rig.ros2.actuator_link.Ros2ActuatorLink each,
    ``ports`` then their namespaces), the shared camera feed and sensor; ``closed`` arms were held
    and disabled (their close problems in ``close_errors``)."""

    links: dict[str, Any]
    ports: dict[str, str]
    feed: SharedFrameFeed
    sensor: BudgetedArmSetSensor
    camera: str
    options: LinkOptions
    closed: set[str] = field(default_factory=set)
    close_errors: dict[str, str] = field(default_factory=dict)

    def start(self) -> None:
        """ENABLE every box (from now on each wants a command every 250 ms); the links' time is
        the host's ``time.monotonic()``."""
        for link in self.links.values():
            link.connect(t_now=time.monotonic())

    def close_arm(self, name: str) -> None:
        """Hold and DISABLE arm ``name``'s box (once; never raises)."""
        if name in self.closed:
            return
        self.closed.add(name)
        link = self.links[name]
        link.close()
        self.close_errors[name] = link.close_error

    def close(self) -> None:
        """Hold and DISABLE every box, stop the tracking and the camera. Never raises."""
        for name in self.links:
            self.close_arm(name)
        for step in (self.sensor.close, self.feed.close):
            try:
                step()
            except Exception:  # noqa: BLE001 - closing must go on
                pass

    def arm_session(self, name: str, sensor: Any) -> ServoSession:
        """Arm ``name``'s view as a :class:`rig.loop.servo_session.ServoSession` (for its summary)."""
        link = self.links[name]
        return ServoSession(link, self.options, self.feed, sensor, port=getattr(link, "port", self.ports[name]),
                            camera=self.camera, wall_clock=True)


def open_arm_set_session(setups: Mapping[str, LoopSetup], ports: Mapping[str, str], camera: str,
                         scene_camera: StereoCamera, options: LinkOptions, camera_timeout: float = 2.0,
                         participant: Any = None, processes: bool = False) -> ArmSetSession:
    """Open every arm's box (PING, GET_STATE: nothing enabled, nothing moved; a box that does not
    answer or does not fit its arm: one line naming the arm and the port) and the camera; check
    its first frame's size against ``scene_camera`` (at the rig's image scale) and track every
    sleeve in it once, before any motion. ``options.kind`` ros2: ``ports`` are the arms' ROS 2
    namespaces, each arm's driver reached by a rig.ros2.actuator_link.Ros2ActuatorLink on
    ``participant`` (one of dds_config.open_participant for the process; its first measured_js
    awaited, nothing enabled); a ``ros2:LEFT,RIGHT`` camera on that participant too.
    ``processes``: the tracker's arms but the first in worker processes of their own
    (cvs.tracking.arm_set), started before any box is opened."""
    from wristmark.cvs.sources.open_source import SourceOptions
    from wristmark.rig.link.actuator_driver import ActuatorDriver, ActuatorError
    from wristmark.rig.loop.hardware_session import first_frame
    from wristmark.rig.loop.servo_session import HW_TIMEOUT_S
    from wristmark.rig.ros2.image_source import open_frame_source

    links: dict[str, Any] = {}
    first_setup = next(iter(setups.values()))
    timeout = options.timeout if options.timeout is not None else HW_TIMEOUT_S
    cam = first_setup._scaled(scene_camera)
    sensor = BudgetedArmSetSensor(cam, [s.marker for s in setups.values()], first_setup.rig.tracking_budget,
                                  magnify=first_setup.rig.tracker_magnify, processes=processes)
    try:
        for name, setup in setups.items():
            try:
                if options.kind == "ros2":  # the arm's driver on a ROS 2 graph (rig/ros2/actuator_link.py)
                    from wristmark.models.arm_spec import actuator_names
                    from wristmark.rig.ros2.actuator_link import Ros2ActuatorLink

                    links[name] = Ros2ActuatorLink(ports[name], require_operating_state=options.operating_state,
                                                   names=actuator_names(setup.params), participant=participant)
                else:
                    driver = ActuatorDriver(ports[name], options.baudrate, timeout, options.retries,
                                            params=setup.params)
                    links[name] = SerialLink(driver)
                links[name].probe()
            except ActuatorError as e:
                raise type(e)(f"arm '{name}' on {ports[name]}: {e}") from None
        source = open_frame_source(camera, SourceOptions(timeout=camera_timeout), participant=participant)
    except BaseException:
        for link in links.values():
            link.close()
        sensor.close()
        raise
    session = ArmSetSession(links, dict(ports), SharedFrameFeed(LatestFrameFeed(source)), sensor, camera, options)
    try:
        first = first_frame(session.feed.feed, cam, camera)
        sensor.results(first)  # loads the tracker's compiled kernels before any motion (no budget) ...
        sensor.tracker.track(first.left, first.right)  # ... and those of the tracking in each arm's boxes
    except BaseException:
        session.close()
        raise
    return session


# -- the run ------------------------------------------------------------------------------------
@dataclass
class ArmSetRun:
    """Every arm's outcome (log, counters, why it stopped) and the least distance [m] between any
    two arms' model bodies (commanded, shifted by their vision offsets) over the cycles."""

    outcomes: dict[str, ServoOutcome]
    least_model_distance_m: float = float("inf")
    tracking_ms: list[float] = field(default_factory=list)


def _lockstep_start(loops: Mapping[str, ServoLoop], psi0: Mapping[str, Array], dt: float) -> None:
    """Every arm ramped from where its encoders say it is to its start (one target per cycle
    each, within its velocity limits), then resting there :data:`SETTLE_AT_START_S`; the boxes
    fed every cycle (ServoLoop.start_at, for several arms at once)."""
    targets = {n: clamp_psi(loop.params, psi0[n]) for n, loop in loops.items()}
    before = {}
    for n, loop in loops.items():
        with on_arm(n):
            before[n] = np.asarray(loop.link.measured_actuators(), float)
    ramps = {n: ramp_to(loop.params, psi_from_actuators(loop.params, before[n], delta_hint=targets[n]), targets[n], dt)
             for n, loop in loops.items()}
    steps = max(len(r) for r in ramps.values()) + 1 + int(round(SETTLE_AT_START_S / dt))
    t = max(loop.t for loop in loops.values())
    for i in range(steps):
        for n, loop in loops.items():
            loop.psi_cmd = ramps[n][i] if i < len(ramps[n]) else targets[n]
            with on_arm(n):
                loop.send(loop.psi_cmd)
        t += dt
        for n, loop in loops.items():
            with on_arm(n):
                loop.advance_to(t)
    for n, loop in loops.items():
        if loop.controller is not None and loop.controller.uses_encoders:  # where the ramp left each play
            with on_arm(n):
                loop.controller.note_start_move(before[n], np.asarray(loop.link.measured_actuators(), float))


def start_gap(setups: Mapping[str, LoopSetup], psi0: Mapping[str, Array], bases: Mapping[str, Array]) -> float:
    """Least distance [m] between the arms' model bodies at their start configurations (scene {w})."""
    return least_distance(bodies_at({n: s.params for n, s in setups.items()}, psi0, bases))


def run_arm_set(setups: Mapping[str, LoopSetup], trajs: Mapping[str, Trajectory], session: ArmSetSession,
                psi0: Mapping[str, Array], bases: Mapping[str, Array], clearance: float, settle: float,
                recorder: Any = None, on_cycle: Callable[[str, Any], None] | None = None) -> ArmSetRun:
    """Every arm to its start, then every trajectory closed loop in lockstep (module docstring);
    ``clearance`` [m] kept between the arms' bodies (0: none); ``settle`` [s] of holding the
    starts before the walks; ``recorder`` (rig.recording.servo_recorder.ServoRecorder of every
    arm) records each arm's cycles and is closed at the end; ``on_cycle(arm, record)`` sees
    every cycle of every arm (the live view's). Closes the session (every box held and
    disabled). Safe stops are reported in each arm's outcome, never raised."""
    from wristmark.solvers.controller_registry import make_controller

    names = list(setups)
    rig = setups[names[0]].rig
    dt = rig.control_dt
    outs = {n: ServoOutcome(RunLog.for_arm(setups[n].params)) for n in names}
    stats = {n: PhaseStats() for n in names}
    run = ArmSetRun(outs)
    wall0 = time.perf_counter()
    loops: dict[str, ServoLoop] = {}
    try:
        controllers = {n: make_controller(s.params, s.controller) for n, s in setups.items()}
        bad = [n for n, c in controllers.items() if clearance > 0 and not c.supports_obstacles]
        if bad:
            raise ConfigError(f"several arms: controller '{setups[bad[0]].controller.kind}' cannot keep a "
                              "clearance; use kind qp or set the scene's clearance to 0")
    except BaseException:
        session.close()
        raise
    try:
        session.start()
        for n, s in setups.items():
            W = np.asarray(s.host_camera.T_world_left, float)
            link: Any = session.links[n]
            rig_n = s.rig
            if s.model is not None:  # --model NAME=FILE: command the identified arm (rig.loop.model_loop)
                from wristmark.rig.loop.model_loop import model_rig, use_model

                link = use_model(link, s.params, s.model, controllers[n], rig_n.control_dt)
                rig_n = model_rig(rig_n, s.model)
            loops[n] = ServoLoop(s.params, rig_n, link, frames=session.feed,
                                 sensor=session.sensor.view(n, W), controller=controllers[n], wall_clock=True,
                                 frame_wait=s.rig.frame_wait,
                                 on_cycle=_cycle_hook(recorder, on_cycle, loops, session.links, n))
        _lockstep_start(loops, psi0, dt)
        _walk(loops, trajs, session, run, stats, bases, clearance, int(round(settle / dt)))
    except (WristmarkError, KeyboardInterrupt) as e:  # every arm held and disabled below
        cause, why = stop_cause(e)
        t_now = max((loop.t for loop in loops.values()), default=float("nan"))
        for n in names:
            if not outs[n].stopped:
                outs[n].stopped, outs[n].cause = why, cause
                outs[n].t_stop = loops[n].elapsed(t_now) if n in loops else float("nan")
    finally:
        session.close()
        if recorder is not None:
            recorder.close()
        for n in names:
            out = outs[n]
            _count(out, stats[n])
            out.close_error = session.close_errors.get(n, "")
            out.wall_time_s = time.perf_counter() - wall0
            if n in loops:
                out.ready_after_arrival_ms = list(loops[n].ready_after_arrival_ms)
                out.play_probe = probe_report(loops[n].play_fits, loops[n].play_probe_note)
                ctrl = loops[n].controller
                out.play_shrinks = ctrl.play_shrinks if ctrl is not None else 0
    return run


def _cycle_hook(recorder: Any, on_cycle: Callable[[str, Any], None] | None, loops: Mapping[str, ServoLoop],
                links: Mapping[str, Any], name: str) -> Any:
    """Arm ``name``'s per-cycle hook: its cycle recorded (with its box's latest reading) and
    handed to ``on_cycle`` (None without either)."""
    if recorder is None and on_cycle is None:
        return None

    def hook(rec: Any) -> None:
        if recorder is not None:
            recorder.record(rec, loops[name], links[name], arm=name)
        if on_cycle is not None:
            on_cycle(name, rec)

    return hook


def _walk(loops: Mapping[str, ServoLoop], trajs: Mapping[str, Trajectory], session: ArmSetSession, run: ArmSetRun,
          stats: Mapping[str, PhaseStats], bases: Mapping[str, Array], clearance: float, n_settle: int) -> None:
    """The cycles of :func:`run_arm_set` after the start: settle, then walk, in lockstep."""
    names = list(loops)
    rig = loops[names[0]].rig
    dt = rig.control_dt
    memory = {n: TrackingMemory() for n in names}
    active = list(names)
    settle = {n: n_settle for n in names}
    for n in names:  # a controller that probes its play: settle and probe, one arm at a time
        ctrl = loops[n].controller
        if ctrl is None or not ctrl.wants_play_probe:
            continue
        others = {m: loops[m].link for m in active if m != n}  # through an identified model's link, if any
        try:
            with feeding_others(loops[n], others), session.feed.solo(), on_arm(n):
                loops[n].advance_to(time.monotonic())  # its cycles from now (an arm probed before took seconds)
                settle[n] = loops[n].probe_play(trajs[n], "servo", run.outcomes[n].log, stats[n], memory[n],
                                                settle[n])
        except CameraStalledError:
            raise
        except MarkerLostError as e:
            _stop_arm(session, run, loops, n, e, loops[n].t)
            active.remove(n)
    n_cycles = max(settle[n] + int(np.floor(trajs[n].duration / dt)) + 1 for n in names)
    t0 = max(loop.t for loop in loops.values()) + dt
    offsets: dict[str, Array] = {}
    k = 0
    while k < n_cycles and active:
        session.feed.begin_cycle()
        t_k = t0 + k * dt
        targets = {n: cycle_target(trajs[n], rig, k, t_k, settle[n]) for n in active}
        for n in active:
            with on_arm(n):
                loops[n].advance_to(t_k)
        missed = min(int((time.monotonic() - t_k) // dt), n_cycles - 1 - k)
        if missed > 0:  # a whole cycle late: skip to the current cycle (every box was just polled)
            for n in active:
                stats[n].skipped += missed
            k += missed
            continue
        if clearance > 0:
            model_offsets(loops, offsets)
            set_obstacles(bases, loops, offsets, clearance)
            run.least_model_distance_m = min(run.least_model_distance_m,
                                             least_distance(model_bodies(bases, loops, offsets)))
        for n in list(active):
            out = run.outcomes[n]
            try:
                with on_arm(n):
                    rec = loops[n].step(targets[n], "servo", True, memory[n], stats[n])
                out.log.add(rec)
                hook = loops[n].on_cycle
                if callable(hook):  # as the loop's own cycles (the settle, the probe) do
                    hook(rec)
            except CameraStalledError:
                raise
            except MarkerLostError as e:  # that arm held and disabled; the others walk on
                _stop_arm(session, run, loops, n, e, t_k)
                active.remove(n)
        run.tracking_ms.append(session.sensor.last_ms)
        k += 1


def _stop_arm(session: ArmSetSession, run: ArmSetRun, loops: Mapping[str, ServoLoop], name: str,
              e: MarkerLostError, t: float) -> None:
    """Arm ``name``'s marker stayed lost: log its last cycle, hold and disable its box."""
    out = run.outcomes[name]
    if e.record is not None:
        out.log.add(e.record)
    out.stopped, out.cause, out.t_stop = str(e), "marker-lost", loops[name].elapsed(t)
    session.close_arm(name)
    session.sensor.retire(name)  # its sleeve no longer searched for: the others' cycles keep that time


def stop_cause(e: BaseException) -> tuple[str, str]:
    """(cause, why) of a run-wide safe stop: camera, estop, watchdog, device, interrupted or error."""
    from wristmark.rig.link.actuator_driver import ActuatorError, ActuatorEStopped, ActuatorNotEnabled

    if isinstance(e, KeyboardInterrupt):
        return "interrupted", "interrupted (Ctrl-C / SIGTERM)"
    if isinstance(e, CameraStalledError):
        return "camera", str(e)
    if isinstance(e, ActuatorEStopped):
        return "estop", f"emergency stop: {e}"
    if isinstance(e, ActuatorNotEnabled):
        return ("watchdog" if "watchdog" in str(e) else "device"), str(e)
    if isinstance(e, ActuatorError):
        return "device", f"actuator box not answering: {e}"
    return "error", str(e)
