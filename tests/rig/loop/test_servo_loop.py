"""The servo loop: closed loop removes the plant's errors, a lost marker holds the arm,
jumping measurements are rejected, commands stay in the limits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests import old_defaults
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import tip_position
from wristmark.models.limits import within_limits
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.loop.frame_feed import SynchronousFeed
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.servo_loop import MarkerLostError, ServoLoop
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.rig.recording.run_log import RunLog
from wristmark.rig.targets.trajectories import Trajectory
from wristmark.sim.optical_tracker import OpticalTracker
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.setup import load_setup, make_direct_loop
from wristmark.sim.truth import SimulatedTruth
from wristmark.sim.truth_sensor import NoisyTruthSensor, TruthClockSource
from wristmark.solvers.controller_registry import make_controller

P = RobotParams()
PLANT = PlantParams(bend_gain=(0.95, 0.92), plane_offset=(0.02, -0.03), actuator_tau=0.03,
                    backlash=(0.004, 5e-5, 3e-5, 3e-5, 3e-5, 3e-5))
RIG = old_defaults.rig(sensor="truth-noise", truth_noise_rms=1e-4, settle_time=1.0, max_lost_cycles=5)


def _line() -> Trajectory:
    c = tip_position(P, HOME_PSI)
    return Trajectory(np.array([c, c + [0.01, 0.0, 0.005]]), 0.01)


PSI0 = solve_tip_ik(P, _line().sample(0)[0], np.array(HOME_PSI)).psi


def _plant() -> TruePlant:
    return TruePlant(P, PLANT, psi0=PSI0)


def _loop(sensor: object, closed: bool, rig: RigConfig = RIG, kind: str = "qp",
          plant: TruePlant | None = None) -> tuple[ServoLoop, TruePlant]:
    plant = plant if plant is not None else _plant()
    link = DirectLink(plant)
    loop = ServoLoop(P, rig, link, frames=SynchronousFeed(TruthClockSource(lambda: link.time)) if closed else None,
                     sensor=sensor if closed else None,  # type: ignore[arg-type]
                     truth=SimulatedTruth(plant, OpticalTracker(1.2e-4, seed=1)),
                     controller=make_controller(P, old_defaults.controller(kind=kind)) if closed else None)
    loop.start_at(PSI0)
    return loop, plant


def _mean_err(log: RunLog, phase: str) -> float:
    return float(np.mean([np.linalg.norm(r.p_true - r.p_des) for r in log.phase(phase)]))


@pytest.mark.parametrize("kind", ["qp", "paper"])
def test_closed_loop_removes_most_of_the_open_loop_error(kind: str) -> None:
    log = RunLog()
    ol, _ = _loop(None, False)
    ol.run(_line(), "open", False, log)
    plant = _plant()
    cl, _ = _loop(NoisyTruthSensor(plant, 1e-4, seed=2), True, kind=kind, plant=plant)
    cl.run(_line(), "closed", True, log, settle=1.0)
    assert _mean_err(log, "open") > 1e-3
    assert _mean_err(log, "closed") < 0.4 * _mean_err(log, "open")
    assert all(within_limits(P, r.psi_cmd) for r in log.records)


class _Blinking:
    """Real measurements until cycle ``lose_at``, then nothing (marker out of view)."""

    def __init__(self, plant: TruePlant, lose_at: int) -> None:
        self.inner = NoisyTruthSensor(plant, 1e-4, seed=3)
        self.n = 0
        self.lose_at = lose_at

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        self.n += 1
        if self.n > self.lose_at:
            return TipMeasurement(False, None, "marker not found")
        return self.inner.measure(frame)  # type: ignore[arg-type]


def test_lost_marker_holds_then_stops() -> None:
    plant = _plant()
    loop, _ = _loop(_Blinking(plant, lose_at=8), True, plant=plant)
    log = RunLog()
    with pytest.raises(MarkerLostError, match="marker lost"):
        loop.run(_line(), "closed", True, log, settle=0.0)
    held = [r for r in log.records if not r.meas_ok]
    assert len(held) == RIG.max_lost_cycles + 1
    # while lost the command does not change: the arm is held
    assert all(np.array_equal(held[0].psi_cmd, r.psi_cmd) for r in held)
    a = plant.measured_actuators()
    plant.advance(1.0)
    np.testing.assert_allclose(plant.measured_actuators(), a, atol=1e-12)


class _Jumpy:
    def __init__(self, plant: TruePlant) -> None:
        self.inner = NoisyTruthSensor(plant, 1e-5, seed=4)
        self.n = 0

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        self.n += 1
        m = self.inner.measure(frame)  # type: ignore[arg-type]
        if self.n == 10:
            assert m.p_world is not None
            return TipMeasurement(True, m.p_world + np.array([0.01, 0, 0]))
        return m


def test_a_jumping_measurement_is_rejected() -> None:
    plant = _plant()
    loop, _ = _loop(_Jumpy(plant), True, plant=plant)
    log = RunLog()
    loop.run(_line(), "closed", True, log, settle=0.0)
    rej = [r for r in log.records if r.rejected]
    assert len(rej) == 1
    assert np.allclose(rej[0].psi_cmd, log.records[8].psi_cmd)


def test_config_rejects_latency_longer_than_cycle() -> None:
    with pytest.raises(Exception, match="vision_latency"):
        dataclasses.replace(RIG, control_dt=0.03, vision_latency=0.05).validate()


def test_start_at_ramps_within_velocity_limits_from_where_the_arm_is() -> None:
    from wristmark.models.actuation import psi_from_actuators
    from wristmark.models.limits import wrap_angle

    setup = load_setup()
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"))
    loop = make_direct_loop(setup, np.asarray(HOME_PSI), closed_loop=False)
    sent: list[np.ndarray] = []
    inner = loop.link.send_target
    loop.link.send_target = lambda a: (sent.append(np.asarray(a, float).copy()), inner(a))[1]  # type: ignore[method-assign]
    far = np.asarray(HOME_PSI) + np.array([0.5, 0.01, -0.4, 2.5, 0.3, -3.0])
    loop.start_at(far)
    psis = [np.asarray(HOME_PSI)] + [psi_from_actuators(setup.params, a, delta_hint=far) for a in sent]
    vmax = np.asarray(setup.params.max_velocity) * setup.rig.control_dt
    for a, b in zip(psis[:-1], psis[1:]):
        d = b - a
        d[3], d[5] = wrap_angle(d[3]), wrap_angle(d[5])
        assert np.all(np.abs(d) <= vmax * (1 + 1e-9) + 1e-12)
    assert len(sent) > 10  # a real ramp, not one jump
    np.testing.assert_allclose(loop.psi_cmd, far, atol=1e-12)


def test_start_at_where_the_arm_already_is_sends_one_target() -> None:
    setup = load_setup()
    loop = make_direct_loop(setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise")),
                            np.asarray(HOME_PSI), closed_loop=False)
    sent: list[np.ndarray] = []
    inner = loop.link.send_target
    loop.link.send_target = lambda a: (sent.append(np.asarray(a)), inner(a))[1]  # type: ignore[method-assign]
    loop.start_at(np.asarray(HOME_PSI))
    assert len(sent) == 1
