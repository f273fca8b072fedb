"""Delay compensation: the model's predicted tip motion from a frame's capture to the command is
exactly the nominal forward kinematics of the commanded (lagged) configurations; a loop whose
measurements arrive with a known latency longer than a cycle tracks better with it; the
in-process bench's fixed latency (capture at the cycle's start, command ``vision_latency`` later)
leaves it exactly zero, so the in-process runs are unchanged."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest

from tests import old_defaults
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics, tip_position
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.loop.delay_compensation import DelayCompensator
from wristmark.rig.loop.frame_feed import SynchronousFeed
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.rig.recording.run_log import RunLog
from wristmark.rig.targets.trajectories import Trajectory
from wristmark.sim.optical_tracker import OpticalTracker
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.truth import SimulatedTruth
from wristmark.sim.truth_sensor import NoisyTruthSensor, TruthClockSource
from wristmark.solvers.controller_registry import make_controller

P = RobotParams()
PSI_A = np.array(HOME_PSI, float)
PSI_B = PSI_A + np.array([0.05, 0.004, 0.08, 0.3, -0.06, 0.2])
PSI_C = PSI_B + np.array([-0.02, 0.002, 0.04, -0.1, 0.05, 0.1])


def test_prediction_with_instant_commands_is_the_fk_of_the_commands_sent_in_between() -> None:
    dc = DelayCompensator(P, tau=0.0)
    dc.record(0.00, PSI_A)
    dc.record(0.06, PSI_B)
    dc.record(0.12, PSI_C)
    tip = lambda q: tip_position(P, q)  # noqa: E731
    # captured before the last two commands, compensated to after both
    np.testing.assert_allclose(dc.predicted_motion(0.05, 0.13), tip(PSI_C) - tip(PSI_A), rtol=0, atol=1e-15)
    np.testing.assert_allclose(dc.predicted_motion(0.07, 0.125), tip(PSI_C) - tip(PSI_B), rtol=0, atol=1e-15)
    assert np.all(dc.predicted_motion(0.065, 0.11) == 0.0)  # no command in between
    # "now" before the capture (a frame captured after the cycle's start): moved back as far
    np.testing.assert_allclose(dc.predicted_motion(0.13, 0.05), tip(PSI_A) - tip(PSI_C), rtol=0, atol=1e-15)
    assert np.all(dc.predicted_motion(0.07, 0.07) == 0.0)
    assert np.linalg.norm(tip(PSI_C) - tip(PSI_A)) > 1e-3  # the check above is not trivial
    p = np.array([0.01, -0.02, 0.1])
    np.testing.assert_allclose(dc.compensate(p, 0.05, 0.13), p + tip(PSI_C) - tip(PSI_A), atol=1e-15)


def test_the_measured_orientation_is_turned_on_by_the_models_turn_of_the_tip_frame() -> None:
    dc = DelayCompensator(P, tau=0.0)
    dc.record(0.00, PSI_A)
    dc.record(0.06, PSI_B)
    dc.record(0.12, PSI_C)
    rot = lambda q: forward_kinematics(P, q).T_world_tip[:3, :3]  # noqa: E731
    turn = dc.predicted_turn(0.05, 0.13)
    np.testing.assert_allclose(turn, rot(PSI_C) @ rot(PSI_A).T, rtol=0, atol=1e-12)
    assert np.degrees(np.arccos(np.clip((np.trace(turn) - 1) / 2, -1, 1))) > 1.0  # not trivial
    assert np.array_equal(dc.predicted_turn(0.065, 0.11), np.eye(3))  # no command in between
    assert np.array_equal(dc.predicted_turn(0.07, 0.07), np.eye(3))
    np.testing.assert_allclose(dc.predicted_turn(0.13, 0.05), turn.T, rtol=0, atol=1e-12)  # moved back
    # a measurement that is the model's orientation at capture becomes the model's at "now"
    np.testing.assert_allclose(dc.compensate_rotation(rot(PSI_A), 0.05, 0.13), rot(PSI_C), rtol=0, atol=1e-12)
    assert np.array_equal(DelayCompensator(P).predicted_turn(0.0, 1.0), np.eye(3))  # no history


def test_prediction_with_a_lag_follows_the_first_order_response_of_every_actuator() -> None:
    tau = 0.04
    dc = DelayCompensator(P, tau=tau)
    dc.record(0.00, PSI_A)
    dc.record(0.06, PSI_B)
    dc.record(0.12, PSI_C)
    a_a, a_b, a_c = (actuators_from_psi(P, q) for q in (PSI_A, PSI_B, PSI_C))
    # by hand: the actuators settled at A, then exponentially towards B from 0.06, towards C from 0.12
    a_012 = a_b + (a_a - a_b) * math.exp(-0.06 / tau)

    def at(t: float) -> np.ndarray:
        if t < 0.06:
            return a_a
        if t < 0.12:
            return a_b + (a_a - a_b) * math.exp(-(t - 0.06) / tau)
        return a_c + (a_012 - a_c) * math.exp(-(t - 0.12) / tau)

    def tip_at(t: float, hint: np.ndarray) -> np.ndarray:
        return tip_position(P, psi_from_actuators(P, at(t), delta_hint=hint))

    for t_c, t_n, hint_c, hint_n in ((0.05, 0.15, PSI_A, PSI_C), (0.09, 0.11, PSI_B, PSI_B),
                                     (0.10, 0.20, PSI_B, PSI_C)):
        expected = tip_at(t_n, hint_n) - tip_at(t_c, hint_c)
        np.testing.assert_allclose(dc.predicted_motion(t_c, t_n), expected, rtol=0, atol=1e-12)
    # the lagged model moves less over a short gap than the instant one
    instant = DelayCompensator(P, tau=0.0)
    for t, q in ((0.0, PSI_A), (0.06, PSI_B), (0.12, PSI_C)):
        instant.record(t, q)
    assert np.linalg.norm(dc.predicted_motion(0.05, 0.13)) < np.linalg.norm(instant.predicted_motion(0.05, 0.13))


def test_a_cycles_motion_and_turn_solve_the_lagged_model_once_per_instant(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A cycle asks for the tip's motion and its turn between the same two instants: with a lag
    each instant is one solve of the actuators, the same answer as solving afresh, and a new
    command makes it solve again."""
    import wristmark.rig.loop.delay_compensation as module
    solves: list[float] = []

    def counted(params: RobotParams, a: np.ndarray, delta_hint: np.ndarray) -> np.ndarray:
        solves.append(1.0)
        return psi_from_actuators(params, a, delta_hint=delta_hint)

    monkeypatch.setattr(module, "psi_from_actuators", counted)
    dc = DelayCompensator(P, tau=0.04)
    dc.record(0.00, PSI_A)
    dc.record(0.06, PSI_B)
    motion, turn = dc.predicted_motion(0.05, 0.09), dc.predicted_turn(0.05, 0.09)
    assert len(solves) == 2
    fresh = DelayCompensator(P, tau=0.04)
    fresh.record(0.00, PSI_A)
    fresh.record(0.06, PSI_B)
    assert np.array_equal(fresh.predicted_turn(0.05, 0.09), turn)
    assert np.linalg.norm(motion) > 1e-4
    dc.record(0.12, PSI_C)  # a new command: the lag's curve after 0.12 changed, solve again
    expected = fresh_motion(0.05, 0.15)
    solves.clear()
    np.testing.assert_allclose(dc.predicted_motion(0.05, 0.15), expected, rtol=0, atol=1e-15)
    assert len(solves) == 2


def fresh_motion(t_capture: float, t_now: float) -> np.ndarray:
    """The lagged model's motion (tau 0.04 s) over A, B, C sent at 0, 0.06, 0.12 s, from a new history."""
    dc = DelayCompensator(P, tau=0.04)
    for t, q in ((0.0, PSI_A), (0.06, PSI_B), (0.12, PSI_C)):
        dc.record(t, q)
    return dc.predicted_motion(t_capture, t_now)


@pytest.mark.parametrize("tau", [0.0, 0.07])
def test_prediction_with_a_reach_arrives_at_each_command_one_reach_after_its_send(tau: float) -> None:
    """The --model link inverts the motors' lag: each target is reached a cycle after it went out,
    along the lag's curve (linear without a lag); a frame captured after its cycle's start is then
    moved back by the motion the arm made in between, not by none (the instant model's)."""
    reach = 0.06
    dc = DelayCompensator(P, tau=tau, reach=reach)
    dc.record(0.00, PSI_A)
    dc.record(0.045, PSI_B)
    a_a, a_b = actuators_from_psi(P, PSI_A), actuators_from_psi(P, PSI_B)
    tip = lambda q: tip_position(P, q)  # noqa: E731
    np.testing.assert_allclose(dc.predicted_motion(0.04, 0.045 + reach), tip(PSI_B) - tip(PSI_A), atol=1e-12)
    gap = 0.03
    share = gap / reach if tau == 0 else (1 - math.exp(-gap / tau)) / (1 - math.exp(-reach / tau))
    half = psi_from_actuators(P, a_a + share * (a_b - a_a), delta_hint=PSI_B)
    np.testing.assert_allclose(dc.predicted_motion(0.04, 0.045 + gap), tip(half) - tip(PSI_A), atol=1e-12)
    # a frame captured 16 ms after the next cycle's start (0.06) is moved back to that start
    instant = DelayCompensator(P, tau=0.0)
    instant.record(0.00, PSI_A)
    instant.record(0.045, PSI_B)
    back = dc.predicted_motion(0.076, 0.06)
    assert np.linalg.norm(back) > 0.1 * np.linalg.norm(tip(PSI_B) - tip(PSI_A))
    assert np.all(instant.predicted_motion(0.076, 0.06) == 0.0)
    with pytest.raises(ValueError, match="reach"):
        DelayCompensator(P, reach=-0.01)


def test_history_refuses_time_going_back_and_forgets_beyond_its_horizon() -> None:
    dc = DelayCompensator(P, tau=0.0, horizon=0.5)
    for k in range(40):
        dc.record(0.06 * k, PSI_A if k < 39 else PSI_B)
    assert len(dc._sent) <= 10
    with pytest.raises(ValueError, match="must not decrease"):
        dc.record(1.0, PSI_A)
    # a capture older than the history is predicted from its oldest command
    np.testing.assert_allclose(dc.predicted_motion(0.0, 10.0), tip_position(P, PSI_B) - tip_position(P, PSI_A),
                               atol=1e-15)


# -- in the loop -----------------------------------------------------------------------------
PLANT = PlantParams(bend_gain=(0.95, 0.92), plane_offset=(0.02, -0.03), actuator_tau=0.04)
LATENCY = 0.13  # [s] injected capture -> command latency: more than two 60 ms cycles


class _RecordingLink(DirectLink):
    """A direct link that steps the plant in 2 ms steps and remembers the true tip at each."""

    def __init__(self, plant: TruePlant) -> None:
        super().__init__(plant)
        self.t_hist: list[float] = [plant.time]
        self.tip_hist: list[np.ndarray] = [plant.true_shape().tip]

    def advance_to(self, t: float) -> None:
        while self.arm.time < t - 1e-12:
            self.arm.advance(min(0.002, t - self.arm.time))
            self.t_hist.append(self.arm.time)
            self.tip_hist.append(self.arm.true_shape().tip)

    def tip_at(self, t: float) -> np.ndarray:
        tips = np.asarray(self.tip_hist)
        return np.array([np.interp(t, self.t_hist, tips[:, i]) for i in range(3)])


class _LateFrames(TruthClockSource):
    """Frames stamped ``LATENCY`` before now: the camera hands out old frames."""

    def read(self) -> StereoFrame:
        f = super().read()
        return dataclasses.replace(f, t_capture=f.t_capture - LATENCY)


class _LateSensor:
    """The true tip at the frame's capture instant (from the link's history), exactly."""

    def __init__(self, link: _RecordingLink) -> None:
        self.link = link

    def measure(self, frame: StereoFrame, axis_hint_world: np.ndarray | None = None) -> TipMeasurement:
        return TipMeasurement(True, self.link.tip_at(frame.t_capture), t_capture=frame.t_capture,
                              frame_index=frame.index)


def _clock_of(link: DirectLink) -> Callable[[], float]:
    return lambda: link.time


def _line() -> Trajectory:
    c = tip_position(P, HOME_PSI)
    return Trajectory(np.array([c, c + [0.012, 0.0, 0.006], c + [0.012, 0.01, 0.0]]), 0.01)


def _square() -> Trajectory:
    """Twice round a 12 mm square in a tilted plane (~10 s at 10 mm/s)."""
    c = tip_position(P, HOME_PSI)
    corners = [c, c + [0.012, 0.0, 0.0], c + [0.012, 0.006, 0.01], c + [0.0, 0.006, 0.01]]
    return Trajectory(np.array(corners * 2 + [c]), 0.01)


def _late_run(compensate: bool, tau: float, learn_window: float = 5.0, path: Callable[[], Trajectory] = _line,
              after: float = 0.0) -> float:
    """Mean |true tip - desired| [m] of a ``path`` followed with measurements LATENCY old, over its
    cycles from ``after`` [s] on (learn_window: the rig's ``delay_compensation_learn_window``, 0:
    the model's motion as it is)."""
    psi0 = solve_tip_ik(P, path().sample(0)[0], np.array(HOME_PSI)).psi
    plant = TruePlant(P, PLANT, psi0=psi0)
    link = _RecordingLink(plant)
    rig = old_defaults.rig(sensor="truth-noise", settle_time=1.0, delay_compensation=compensate,
                           delay_compensation_tau=tau, delay_compensation_learn_window=learn_window)
    loop = ServoLoop(P, rig, link, frames=SynchronousFeed(_LateFrames(lambda: link.time)), sensor=_LateSensor(link),
                     truth=SimulatedTruth(plant, OpticalTracker(1.2e-4, seed=1)),
                     controller=make_controller(P, old_defaults.controller(kind="qp")))
    loop.start_at(psi0)
    log = RunLog()
    loop.run(path(), "servo", True, log, settle=1.0)
    t0 = log.phase("servo")[0].t
    errs = [np.linalg.norm(r.p_true - r.p_des) for r in log.phase("servo") if r.t - t0 >= after]
    assert all(np.isfinite(r.latency_ms) and r.latency_ms > 1000 * LATENCY for r in log.phase("servo") if r.meas_ok)
    return float(np.mean(errs))


@pytest.mark.slow
@pytest.mark.parametrize("tau", [0.0, 0.04])
def test_a_loop_with_a_long_known_latency_tracks_better_with_the_compensation(tau: float) -> None:
    without = _late_run(False, tau)
    with_it = _late_run(True, tau)
    assert with_it < 0.75 * without, (with_it, without)


@pytest.mark.slow
def test_the_learnt_motion_map_removes_the_bias_of_the_model_s_gain_errors() -> None:
    """The arm (PLANT: bending gains 0.95 / 0.92, plane offsets) moves less than its model: over
    the 130 ms the model over-predicts its motion and the loop, which acts on the compensated
    measurement, lags (0.15 mm here against 0.07 mm on an arm exactly like its model). Learnt
    from the measured motion between frames (in the first 4 s; the map forgets over 5 s), the
    map removes a part of it: 0.13 mm."""
    model_only = _late_run(True, 0.04, learn_window=0.0, path=_square, after=4.0)
    learnt = _late_run(True, 0.04, learn_window=5.0, path=_square, after=4.0)
    assert learnt < 0.9 * model_only, (learnt, model_only)


@pytest.mark.parametrize("tau", [0.0, 0.04])
def test_the_in_process_bench_latency_leaves_the_loop_unchanged(tau: float) -> None:
    """Capture at the cycle's start, command vision_latency later (< a cycle): the measurement is
    compensated to the cycle's start, its own capture instant, so the model predicts no motion
    (with or without the actuators' lag) and the run is bit-identical."""
    logs = []
    for compensate in (False, True):
        psi0 = solve_tip_ik(P, _line().sample(0)[0], np.array(HOME_PSI)).psi
        plant = TruePlant(P, PLANT, psi0=psi0)
        link = DirectLink(plant)
        rig = old_defaults.rig(sensor="truth-noise", settle_time=1.0, delay_compensation=compensate,
                               delay_compensation_tau=tau)
        loop = ServoLoop(P, rig, link, frames=SynchronousFeed(TruthClockSource(_clock_of(link))),
                         sensor=NoisyTruthSensor(plant, 1e-4, seed=3),
                         controller=make_controller(P, old_defaults.controller(kind="qp")))
        loop.start_at(psi0)
        log = RunLog()
        loop.run(_line(), "servo", True, log, settle=0.5)
        logs.append(np.array([r.psi_cmd for r in log.records]))
    assert logs[0].shape == logs[1].shape and logs[0].shape[0] > 20
    assert np.array_equal(logs[0], logs[1])


# -- the model is the arm's expected configuration, not the dead-band inversion's motor command --
def _inverting_controller() -> tuple[object, np.ndarray]:
    """A qp controller with the encoders' dead-band inversion, stepped until it inverts; returns
    it and the (compensated) configuration it returned last."""
    cfg = old_defaults.controller(kind="qp", backlash_compensation=True, backlash_method="encoders", backlash_start=1.0)
    ctrl = make_controller(P, cfg)
    psi = PSI_A.copy()
    for _ in range(3):
        p = tip_position(P, psi)
        psi = ctrl.step(psi, p, p + np.array([0.002, 0.0, 0.0]), None, 0.06,
                        encoders=actuators_from_psi(P, psi)).psi_next
    return ctrl, psi


def test_output_model_is_the_nominal_behind_the_inversion_and_changes_nothing() -> None:
    ctrl, psi = _inverting_controller()
    twin, psi_twin = _inverting_controller()  # the same steps: the same state
    np.testing.assert_array_equal(psi, psi_twin)
    nominal = ctrl.output_model(psi)  # type: ignore[attr-defined]
    offset = actuators_from_psi(P, psi) - actuators_from_psi(P, nominal)
    assert np.max(np.abs(offset)) > 1e-5  # the motors are commanded across the band
    p = tip_position(P, psi)
    a = ctrl.step(psi, p, p + [0.001, 0, 0], None, 0.06, encoders=actuators_from_psi(P, psi))  # type: ignore
    b = twin.step(psi, p, p + [0.001, 0, 0], None, 0.06, encoders=actuators_from_psi(P, psi))  # type: ignore
    np.testing.assert_array_equal(a.psi_next, b.psi_next)
    plain = make_controller(P, old_defaults.controller(kind="qp"))
    np.testing.assert_array_equal(plain.output_model(psi), psi)
    # a configuration that is not the last one returned is its own model (no state to go by)
    np.testing.assert_array_equal(ctrl.output_model(PSI_B), PSI_B)  # type: ignore[attr-defined]


class _FixedOutput:
    """A controller stand-in whose arm is expected to stay at PSI_A whatever is commanded."""

    def output_model(self, psi: np.ndarray) -> np.ndarray:
        return PSI_A.copy()

    def actuator_targets(self, psi: np.ndarray) -> np.ndarray:  # as Controller's without an inversion
        return actuators_from_psi(P, psi)


class _NullLink:
    time = 0.0

    def send_target(self, actuators: np.ndarray) -> None:
        self.sent = actuators


def test_the_loop_compensates_with_the_arm_expected_not_the_motor_commands() -> None:
    """Commands that move only the motors (the inversion's jumps across the band) predict no tip
    motion: the loop records the controller's output model, not the command it sends."""
    rig = old_defaults.rig(sensor="truth-noise", delay_compensation=True, delay_compensation_tau=0.0)
    loop = ServoLoop(P, rig, _NullLink(), controller=_FixedOutput())  # type: ignore[arg-type]
    loop.t = 0.0
    loop.send(PSI_B)
    loop.t = 0.05
    loop.send(PSI_C)
    np.testing.assert_array_equal(loop.link.sent, actuators_from_psi(P, PSI_C))  # type: ignore[attr-defined]
    assert loop.delay is not None
    np.testing.assert_array_equal(loop.delay.predicted_motion(0.01, 0.06), np.zeros(3))
    plain = ServoLoop(P, rig, _NullLink())  # no controller: the commands are the model
    plain.t = 0.0
    plain.send(PSI_B)
    plain.t = 0.05
    plain.send(PSI_C)
    assert plain.delay is not None
    assert np.linalg.norm(plain.delay.predicted_motion(0.01, 0.06)) > 1e-3
