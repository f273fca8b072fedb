"""SerialLink over a real pty against the in-process emulator: same behaviour as DirectLink up to
micro-unit quantisation, simulated and real time, watchdog, hold, emergency stop, close."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.limits import actuator_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_driver import (
    ActuatorDriver,
    ActuatorEStopped,
    ActuatorNotEnabled,
    ActuatorRejected,
)
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.link.serial_link import SerialLink, SimClock
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.locked_arm import LockedArm
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams

ROOT = Path(__file__).resolve().parents[3]
PARAMS = RobotParams()
PLANT = PlantParams.load(CONFIG_DIR / "plant.yaml")
HOME = np.asarray(HOME_PSI, float)
QUANTUM = 0.5e-6  # [rad or m] largest rounding of an SI value to protocol micro-units
TIP_QUANTUM = 50e-6  # [m] tip displacement of QUANTUM on every actuator (see the first test)


class RecordingEmulator(ActuatorEmulator):
    """The emulator, recording the type of every packet it receives (in order)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.received: list[str] = []
        self._spy = P.StreamParser()

    def receive(self, data: bytes) -> bytes:
        for item in self._spy.feed(data):
            if not isinstance(item, P.ParseError):
                self.received.append(type(item).__name__)
        return super().receive(data)


@dataclass
class Bench:
    link: SerialLink
    emulator: RecordingEmulator
    plant: TruePlant
    clock: SimClock | None


def open_bench(simulated: bool = True) -> Bench:
    plant = TruePlant(PARAMS, PLANT, psi0=HOME)
    clock = SimClock(0.0) if simulated else None
    emu = RecordingEmulator(LockedArm(plant), PARAMS, clock=clock if clock is not None else time.monotonic)
    path = emu.serve_pty()
    link = SerialLink(ActuatorDriver(path, timeout=0.5, params=PARAMS), clock=clock)
    link.connect()
    return Bench(link, emu, plant, clock)


@pytest.fixture
def bench() -> Iterator[Bench]:
    b = open_bench()
    yield b
    b.link.close()
    b.emulator.stop()


def random_targets(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    out = []
    for _ in range(n):
        psi = HOME + rng.uniform(-1, 1, 6) * np.array([0.3, 0.01, 0.3, 1.0, 0.4, 1.0])
        psi[2], psi[4] = abs(psi[2]), abs(psi[4])
        out.append(actuators_from_psi(PARAMS, psi))
    return out


def test_same_commands_give_the_same_plant_as_direct_link(bench: Bench) -> None:
    direct_plant = TruePlant(PARAMS, PLANT, psi0=HOME)
    direct = DirectLink(direct_plant)
    rng = np.random.default_rng(3)
    t = 0.0
    for a in random_targets(rng, 25):
        for link in (bench.link, direct):
            link.send_target(a)
        t += float(rng.choice([0.004, 0.015, 0.045, 0.06, 0.3, 0.7]))  # > 0.25 s too: no watchdog trip
        for link in (bench.link, direct):
            link.advance_to(t)
        assert bench.plant.time == pytest.approx(direct_plant.time, abs=1e-9)
        # targets round to micro-units; lag and backlash are 1-Lipschitz, so the motors stay within it
        np.testing.assert_allclose(
            bench.plant.measured_actuators(), direct_plant.measured_actuators(), rtol=0, atol=QUANTUM + 1e-12
        )
        np.testing.assert_allclose(
            bench.link.measured_actuators(), direct_plant.measured_actuators(), rtol=0, atol=2 * QUANTUM + 1e-12
        )
        # 0.5 µm of backbone at r_b = 2.5 mm is 0.2 mrad of segment-1 bend, ~25 µm at the tip
        # (lever ~0.12 m), two backbones per segment: at most ~50 µm
        assert np.linalg.norm(bench.plant.true_tip() - direct_plant.true_tip()) < TIP_QUANTUM
    assert bench.link.state is not None and bench.link.state.enabled
    assert abs(bench.link.state.clock_ms - 1000 * t) <= 1  # the device clock is the simulated one


def test_simulated_time_never_trips_the_watchdog_however_slow_the_host(bench: Bench) -> None:
    bench.link.advance_to(2.0)  # 2 s in one call: fed every 0.1 s of simulated time
    time.sleep(0.4)  # the host "computes" for longer than the watchdog in real time
    bench.link.send_target(actuators_from_psi(PARAMS, HOME))
    assert bench.link.state is not None and bench.link.state.enabled
    assert not bench.link.state.watchdog_tripped
    assert bench.emulator.received.count("GetState") >= 20


def test_watchdog_still_runs_in_simulated_time(bench: Bench) -> None:
    assert bench.clock is not None
    bench.clock.set(bench.clock() + 0.3)  # simulated time moved without the host feeding it
    with pytest.raises(ActuatorNotEnabled, match="watchdog tripped"):
        bench.link.send_target(actuators_from_psi(PARAMS, HOME))
    assert bench.emulator.watchdog_tripped and not bench.emulator.enabled


@pytest.mark.wallclock
def test_real_time_link_time_is_the_wall_clock_now_not_where_the_loop_last_waited() -> None:
    """A command sent late in a cycle is sent at its own time (the --model link holds its
    lag-inverting target for one cycle from there, rig/link/model_link.py)."""
    b = open_bench(simulated=False)
    try:
        b.link.advance_to(0.1)
        t_then = b.link.time
        assert t_then >= 0.1
        time.sleep(0.05)  # the host tracks a frame: the loop does not advance the link
        assert b.link.time - t_then >= 0.045
    finally:
        b.link.close()
        b.emulator.stop()


@pytest.mark.wallclock
def test_real_time_paces_with_keepalives_and_trips_when_the_host_goes_silent() -> None:
    b = open_bench(simulated=False)
    try:
        t0 = time.monotonic()
        b.link.advance_to(0.6)
        elapsed = time.monotonic() - t0
        assert 0.55 <= elapsed < 1.5
        assert b.emulator.enabled and not b.emulator.watchdog_tripped  # keep-alives every 0.1 s
        assert b.link.stats.keepalives >= 5
        time.sleep(0.4)  # the host hangs: no command for longer than 250 ms
        with pytest.raises(ActuatorNotEnabled, match="watchdog tripped"):
            b.link.send_target(actuators_from_psi(PARAMS, HOME))
    finally:
        b.link.close()
        b.emulator.stop()


def test_hold_stops_the_arm_where_it_is_and_close_disables(bench: Bench) -> None:
    far = actuators_from_psi(PARAMS, HOME + np.array([0.4, 0.01, 0.3, 0.0, 0.3, 0.0]))
    bench.link.send_target(far)
    bench.link.advance_to(0.03)  # mid-move (actuator lag 40 ms)
    bench.link.hold()
    here = bench.plant.measured_actuators()
    bench.link.advance_to(1.0)
    np.testing.assert_allclose(bench.plant.measured_actuators(), here, rtol=0, atol=QUANTUM + 1e-12)
    assert np.max(np.abs(here - far)) > 1e-3  # it really stopped short of the target
    bench.emulator.received.clear()
    bench.link.close()
    assert bench.emulator.received == ["GetState", "SetTarget", "Disable"]
    assert not bench.emulator.enabled
    bench.link.close()  # idempotent
    assert bench.link.close_error == ""


def test_close_never_raises_when_the_device_is_gone(bench: Bench) -> None:
    bench.emulator.stop()
    bench.link.close()
    assert "unreachable" in bench.link.close_error


def test_out_of_limit_target_raises_and_moves_nothing(bench: Bench) -> None:
    before = bench.plant.measured_actuators()
    _, hi = actuator_bounds(PARAMS)
    bad = actuators_from_psi(PARAMS, HOME)
    bad[1] = hi[1] + 0.01
    with pytest.raises(ActuatorRejected, match="d="):
        bench.link.send_target(bad)
    bench.link.advance_to(0.5)
    np.testing.assert_array_equal(bench.plant.measured_actuators(), before)


def test_emergency_stop_is_seen_at_once_and_close_stays_quiet(bench: Bench) -> None:
    bench.link.send_target(actuators_from_psi(PARAMS, HOME + np.array([0.3, 0, 0.2, 0, 0, 0])))
    bench.link.advance_to(0.02)
    bench.emulator.receive(P.encode(P.EStop(seq=200)))  # the box's stop button
    here = bench.plant.measured_actuators()
    with pytest.raises(ActuatorEStopped, match="emergency-stopped"):
        bench.link.advance_to(0.5)
    with pytest.raises(ActuatorEStopped):
        bench.link.send_target(actuators_from_psi(PARAMS, HOME))
    bench.link.close()
    assert bench.link.close_error == ""  # a stopped device is held and disabled already
    np.testing.assert_allclose(bench.plant.measured_actuators(), here, atol=1e-12)


def test_connect_refuses_an_emergency_stopped_device() -> None:
    plant = TruePlant(PARAMS, PLANT, psi0=HOME)
    emu = RecordingEmulator(plant, PARAMS, clock=SimClock())
    with emu:
        path = emu.serve_pty()
        emu.receive(P.encode(P.EStop(seq=1)))
        link = SerialLink(ActuatorDriver(path, timeout=0.5, params=PARAMS), clock=SimClock())
        with pytest.raises(ActuatorEStopped, match="RESET"):
            link.connect()
        link.close()
        assert "Enable" not in emu.received and "SetTarget" not in emu.received
