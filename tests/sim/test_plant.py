"""TruePlant: ideal plant equals the nominal model; lag, backlash, load, stem coupling behave."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.plant_interface import ActuatedArm
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams
from wristmark_testing.reference_chain import chain

PARAMS = RobotParams()
HOME = np.array(HOME_PSI)


def _random_psi(rng: np.random.Generator) -> np.ndarray:
    return np.array(
        [
            rng.uniform(-1.0, 1.0),
            rng.uniform(0.01, 0.12),
            rng.uniform(0.05, 1.4),
            rng.uniform(-3.0, 3.0),
            rng.uniform(0.05, 1.9),
            rng.uniform(-3.0, 3.0),
        ]
    )


def _frames_close(a: object, b: object, tol: float) -> None:
    for name in ("T_world_1b", "T_world_1e", "T_world_2b", "T_world_2e", "T_world_marker", "T_world_tip"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0.0, atol=tol)


def test_implements_protocol() -> None:
    plant: ActuatedArm = TruePlant(PARAMS, PlantParams(), psi0=HOME)
    assert plant.time == 0.0


def test_ideal_plant_equals_model_instant() -> None:
    rng = np.random.default_rng(1)
    plant = TruePlant(PARAMS, PlantParams(), psi0=HOME)
    for _ in range(20):
        q = _random_psi(rng)
        plant.command(actuators_from_psi(PARAMS, q))
        plant.advance(0.01)
        shape = plant.true_shape()
        _frames_close(shape.frames, forward_kinematics(PARAMS, q), 1e-12)
        np.testing.assert_allclose(plant.true_tip(), forward_kinematics(PARAMS, q).tip, rtol=0, atol=1e-12)


def test_ideal_plant_with_lag_equals_model_after_settling() -> None:
    rng = np.random.default_rng(2)
    plant = TruePlant(PARAMS, PlantParams(actuator_tau=0.05), psi0=HOME)
    for _ in range(3):
        q = _random_psi(rng)
        plant.command(actuators_from_psi(PARAMS, q))
        plant.advance(0.3)
        assert np.linalg.norm(plant.true_tip() - forward_kinematics(PARAMS, q).tip) > 1e-6  # still moving
        plant.advance(2.5)
        _frames_close(plant.true_shape().frames, forward_kinematics(PARAMS, q), 1e-12)


def test_ideal_plant_initial_state_is_psi0() -> None:
    plant = TruePlant(PARAMS, PlantParams(actuator_tau=0.05), psi0=HOME)
    _frames_close(plant.true_shape().frames, forward_kinematics(PARAMS, HOME), 1e-12)
    np.testing.assert_allclose(plant.true_psi, HOME, atol=1e-12)


def test_time_advances() -> None:
    plant = TruePlant(PARAMS, PlantParams(), psi0=HOME)
    plant.advance(0.06)
    plant.advance(0.0305)
    assert plant.time == pytest.approx(0.0905, abs=1e-15)


def test_first_order_step_response() -> None:
    tau = 0.05
    plant = TruePlant(PARAMS, PlantParams(actuator_tau=tau), psi0=HOME)
    a0 = plant.measured_actuators()
    step = np.array([0.1, 0.002, 0.0, 0.0, 0.0, 0.0])
    plant.command(a0 + step)
    plant.advance(tau)
    frac = (plant.measured_actuators() - a0)[:2] / step[:2]
    np.testing.assert_allclose(frac, 1.0 - math.exp(-1.0), rtol=1e-9)
    plant.advance(tau)
    frac2 = (plant.measured_actuators() - a0)[:2] / step[:2]
    np.testing.assert_allclose(frac2, 1.0 - math.exp(-2.0), rtol=1e-9)


def test_measured_actuators_follow_commands() -> None:
    plant = TruePlant(PARAMS, PlantParams(actuator_tau=0.04, backlash=(0.002, 1e-4, 5e-5, 5e-5, 5e-5, 5e-5)), psi0=HOME)
    target = actuators_from_psi(PARAMS, HOME + np.array([0.2, 0.01, 0.1, 0.3, -0.2, 0.5]))
    plant.command(target)
    plant.advance(0.06)
    mid = plant.measured_actuators()
    assert np.all(np.abs(mid - target) < np.abs(actuators_from_psi(PARAMS, HOME) - target) + 1e-15)
    plant.advance(3.0)
    np.testing.assert_allclose(plant.measured_actuators(), target, rtol=0, atol=1e-12)


def test_hold_stops_the_motors() -> None:
    plant = TruePlant(PARAMS, PlantParams(actuator_tau=0.05), psi0=HOME)
    a0 = plant.measured_actuators()
    plant.command(a0 + np.array([0.0, 0.01, 0, 0, 0, 0]))
    plant.advance(0.03)
    held = plant.measured_actuators()
    assert held[1] > a0[1]
    plant.hold()
    plant.advance(1.0)
    np.testing.assert_allclose(plant.measured_actuators(), held, atol=1e-15)


def test_backlash_hysteresis_on_reversal() -> None:
    b = 1e-3  # dead-band on the insertion d [m]
    plant = TruePlant(PARAMS, PlantParams(backlash=(0.0, b, 0.0, 0.0, 0.0, 0.0)), psi0=HOME)
    a = plant.measured_actuators()
    d0 = a[1]

    def go(d: float) -> float:
        a[1] = d
        plant.command(a)
        plant.advance(0.01)
        assert plant.measured_actuators()[1] == pytest.approx(d, abs=1e-15)  # encoders see the motor
        return float(plant.true_psi[1])

    # moving up: the output trails the motor by half the dead-band
    assert go(d0 + 0.005) == pytest.approx(d0 + 0.005 - b / 2, abs=1e-12)
    # a reversal smaller than the dead-band does not move the arm
    assert go(d0 + 0.005 - 0.6 * b) == pytest.approx(d0 + 0.005 - b / 2, abs=1e-12)
    # moving down past the play: the output now leads by half the dead-band
    down = go(d0 + 0.002)
    assert down == pytest.approx(d0 + 0.002 + b / 2, abs=1e-12)
    # same commanded position approached from both sides differs by the full dead-band
    from_below = go(d0 + 0.004)  # coming up again
    go(d0 + 0.006)
    from_above = go(d0 + 0.004)
    assert from_above - from_below == pytest.approx(b, abs=1e-12)


def test_bend_gain_and_plane_offset() -> None:
    plant = TruePlant(PARAMS, PlantParams(bend_gain=(0.9, 0.8), plane_offset=(0.05, -0.1)), psi0=HOME)
    q = plant.true_psi
    assert q[2] == pytest.approx(0.9 * HOME[2], abs=1e-12)
    assert q[4] == pytest.approx(0.8 * HOME[4], abs=1e-12)
    assert q[3] == pytest.approx(HOME[3] + 0.05, abs=1e-12)
    assert q[5] == pytest.approx(HOME[5] - 0.1, abs=1e-12)
    assert np.linalg.norm(plant.true_tip() - forward_kinematics(PARAMS, HOME).tip) > 1e-3


def test_stem_coupling_bends_the_stem() -> None:
    plant = TruePlant(PARAMS, PlantParams(stem_coupling=0.2), psi0=HOME)
    shape = plant.true_shape()
    p1b = shape.frames.T_world_1b[:3, 3]
    # the stem bends in segment 1's plane (delta1 = 0 -> towards +x of {1b}), stays length d
    assert p1b[0] > 1e-4
    assert abs(p1b[1]) < 1e-12
    stem = shape.centreline[: np.argmin(np.linalg.norm(shape.centreline - p1b, axis=1)) + 1]
    length = float(np.sum(np.linalg.norm(np.diff(stem, axis=0), axis=1)))
    assert length == pytest.approx(HOME[1], rel=1e-2)
    assert np.linalg.norm(plant.true_tip() - forward_kinematics(PARAMS, HOME).tip) > 1e-3


@pytest.mark.parametrize("force", [(0.1, 0, 0), (0, 0.1, 0), (0, 0, -0.1), (-0.1, 0, 0), (0, -0.1, 0)])
def test_tip_force_deflects_in_its_direction(force: tuple[float, float, float]) -> None:
    base = TruePlant(PARAMS, PlantParams(), psi0=HOME).true_tip()
    loaded = TruePlant(PARAMS, PlantParams(tip_force=force), psi0=HOME).true_tip()
    d = loaded - base
    f = np.asarray(force, float)
    assert np.linalg.norm(d) > 1e-4
    assert d @ f / (np.linalg.norm(d) * np.linalg.norm(f)) > 0.5


def test_stiffer_arm_deflects_less() -> None:
    force = (0.0, 0.1, 0.0)
    base = TruePlant(PARAMS, PlantParams(), psi0=HOME).true_tip()
    soft = TruePlant(PARAMS, PlantParams(tip_force=force, segment_stiffness=(0.2, 0.1)), psi0=HOME).true_tip()
    stiff = TruePlant(PARAMS, PlantParams(tip_force=force, segment_stiffness=(0.8, 0.4)), psi0=HOME).true_tip()
    assert np.linalg.norm(stiff - base) < np.linalg.norm(soft - base)


def test_true_shape_consistent() -> None:
    plant = TruePlant(PARAMS, PlantParams(bend_gain=(0.93, 0.9), tip_force=(0, 0, -0.05)), psi0=HOME)
    shape = plant.true_shape()
    np.testing.assert_allclose(shape.tip, plant.true_tip(), atol=1e-15)
    np.testing.assert_allclose(shape.centreline[0], [0.0, 0.0, 0.0], atol=1e-15)


def test_every_error_source_keeps_the_models_chain_on_random_psi() -> None:
    """Gains, offsets, stem coupling and load change psi (and bend the stem), never the chain: the
    true frames are the model's chain (models.kinematics) at the true psi with the stem bent by
    stem_coupling x theta1, and an independent 4x4 chain agrees, to 1e-12 m."""
    rng = np.random.default_rng(7)
    plant_params = PlantParams(bend_gain=(0.9, 1.1), plane_offset=(0.05, -0.1), stem_coupling=0.2,
                               tip_force=(0.05, -0.03, 0.02))
    plant = TruePlant(PARAMS, plant_params, psi0=HOME)
    lengths = {"L1": PARAMS.segment_lengths[0], "L2": PARAMS.segment_lengths[1], "Lr": PARAMS.rigid_length,
               "lm": PARAMS.marker_offset, "lt": PARAMS.tip_offset}
    for _ in range(10):
        plant.command(actuators_from_psi(PARAMS, _random_psi(rng)))
        plant.advance(0.01)
        q, frames = plant.true_psi, plant.true_shape().frames
        bend = 0.2 * q[2]
        _frames_close(frames, forward_kinematics(PARAMS, q, stem_bend=bend), 1e-12)
        ref = chain(lengths, q, stem_bend=bend)
        for key, T in (("1b", frames.T_world_1b), ("2e", frames.T_world_2e), ("marker", frames.T_world_marker),
                       ("tip", frames.T_world_tip)):
            np.testing.assert_allclose(T, ref[key], rtol=0, atol=1e-12)
