"""The identification's fit (solvers/identification.py) on synthetic data: tips the plant's own
static map gives through a known play history, with noise; it recovers the parameters within
stated tolerances, gives standard errors that cover the error, and flags what cannot be
separated."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wristmark.models.errors import InputError
from wristmark.models.plant_params import PlantParams
from wristmark.models.robot_params import RobotParams
from wristmark.rig.loop.excitation import excitation_plan
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.identification import ExcitationData, identify, play_outputs, predicted_tips

ARM = RobotParams()
UNIT = ControllerConfig().play_max_for(ARM)
TRUTH = PlantParams(bend_gain=(1.06, 0.88), plane_offset=(-0.06, 0.08), stem_coupling=0.04,
                    backlash=(0.006, 8e-5, 8e-5, 8e-5, 7e-5, 7e-5), actuator_tau=0.07,
                    tip_force=(0.03, 0.05, -0.08))


def synthetic(noise: float = 2e-5, poses: int = 24, seed: int = 3) -> ExcitationData:
    """Encoders stepping through an excitation plan (approach, then the pose, 6 cycles each), the
    tip of TRUTH at every pose plus Gaussian noise [m]."""
    from wristmark.models.actuation import actuators_from_psi

    plan = excitation_plan(ARM, UNIT, poses=poses, seed=seed)
    enc, idx, hints = [], [], []
    for q, side in zip(plan.poses, plan.sides):
        a = actuators_from_psi(ARM, q)
        enc += [a + side * plan.approach] * 3 + [a] * 6
        idx.append(len(enc) - 1)
        hints.append(q)
    enc_a = np.array(enc)
    data = ExcitationData(np.arange(len(enc)) * 0.06, enc_a, enc_a, np.array(idx), np.zeros((len(idx), 3)),
                          np.array(hints))
    tips = predicted_tips(ARM, TRUTH, data) + np.random.default_rng(seed).normal(0, noise, (len(idx), 3))
    return dataclasses.replace(data, tips=tips)


def test_play_outputs_follow_the_motor_at_the_edge_of_the_band() -> None:
    m = np.array([[0.0], [1.0], [0.5], [0.0], [0.2]])
    out = play_outputs(m, np.array([0.4]))[:, 0]
    assert out.tolist() == pytest.approx([0.0, 0.8, 0.7, 0.2, 0.2])


@pytest.fixture(scope="module")
def fit():  # type: ignore[no-untyped-def]
    return identify(ARM, synthetic(), UNIT)


def test_recovers_gains_offsets_coupling_and_plays(fit) -> None:  # type: ignore[no-untyped-def]
    p = fit.plant
    assert p.bend_gain == pytest.approx(TRUTH.bend_gain, abs=0.005)
    assert p.plane_offset == pytest.approx(TRUTH.plane_offset, abs=0.005)
    assert p.stem_coupling == pytest.approx(TRUTH.stem_coupling, abs=0.002)
    assert p.backlash[0] == pytest.approx(TRUTH.backlash[0], abs=0.001)  # [rad]
    assert p.backlash[2:] == pytest.approx(TRUTH.backlash[2:], abs=1e-5)  # [m]
    assert fit.rms_m < 4e-5  # the noise's order (2e-5 m per axis)


def test_standard_errors_cover_the_errors(fit) -> None:  # type: ignore[no-untyped-def]
    for key, true in (("bend_gain[0]", 1.06), ("bend_gain[1]", 0.88), ("plane_offset[1]", 0.08),
                      ("stem_coupling", 0.04)):
        assert abs(fit.values[key] - true) < 5 * fit.std_errors[key] + 1e-4, key
        assert fit.std_errors[key] > 0


def test_lists_what_cannot_be_separated(fit) -> None:  # type: ignore[no-untyped-def]
    text = " ".join(fit.not_separable)
    assert "plane_offset[0]" in text and "stem-rotation encoder" in text
    assert "segment_stiffness" in text


def test_an_excitation_that_never_moves_an_actuator_flags_its_play() -> None:
    data = synthetic(poses=12)
    enc = data.encoders.copy()
    enc[:, 5] = enc[0, 5]  # s2b never moves: its play is not seen
    still = dataclasses.replace(data, encoders=enc, targets=enc)
    fit = identify(ARM, still, UNIT)
    assert any("backlash[5]" in note for note in fit.not_separable)


def test_too_few_tips_is_refused_naming_the_cause() -> None:
    data = synthetic(poses=12)
    few = dataclasses.replace(data, tips=np.where(np.arange(12)[:, None] < 5, data.tips, np.nan))
    with pytest.raises(InputError, match="5 measured tips"):
        identify(ARM, few, UNIT)


def test_with_the_camera_fits_where_it_is_and_the_arm_from_one_excitation() -> None:
    from scipy.spatial.transform import Rotation

    truth = dataclasses.replace(TRUTH, plane_offset=(0.0, 0.08))  # o1 is a turn about z_w: the camera's
    data = synthetic(noise=2e-5)
    data = dataclasses.replace(data, tips=predicted_tips(ARM, truth, data)
                               + np.random.default_rng(5).normal(0, 2e-5, data.tips.shape))
    # the camera not where the calibration says: the tips come out moved by the inverse of C
    C = np.eye(4)
    C[:3, :3] = Rotation.from_rotvec([0.02, -0.03, 0.025]).as_matrix()
    C[:3, 3] = [0.004, -0.003, 0.002]
    Ci = np.linalg.inv(C)
    seen = dataclasses.replace(data, tips=data.tips @ Ci[:3, :3].T + Ci[:3, 3])

    plain = identify(ARM, seen, UNIT)
    fit = identify(ARM, seen, UNIT, camera=True)
    assert fit.world_correction is not None and plain.world_correction is None
    # 20 um of noise on tips ~0.1 m from the origin: the turn to ~0.3 mrad, the shift to ~0.1 mm
    assert fit.world_correction[:3, :3] == pytest.approx(C[:3, :3], abs=5e-4)
    assert fit.world_correction[:3, 3] == pytest.approx(C[:3, 3], abs=2e-4)
    assert fit.plant.bend_gain == pytest.approx(truth.bend_gain, abs=0.005)
    assert fit.plant.plane_offset == pytest.approx(truth.plane_offset, abs=0.005)
    assert fit.rms_m < 5e-5 < plain.rms_m  # the arm alone cannot explain a moved camera
    assert "camera_rot[2]" in fit.std_errors and "plane_offset[0]" not in fit.values
    assert any("camera's turn about z_w" in note for note in fit.not_separable)


def test_the_excitation_ramps_some_poses_slowly() -> None:
    plan = excitation_plan(ARM, UNIT, poses=12, seed=1)
    speeds = [plan.speed(i) for i in range(12)]
    assert speeds.count(plan.slow_speed) == 3 and speeds.count(1.0) == 9
    fast = dataclasses.replace(plan, slow_every=0)
    assert plan.duration(0.06, ARM) > fast.duration(0.06, ARM)


def test_a_known_load_on_some_poses_separates_the_stiffness_from_the_arms_own_load() -> None:
    truth = dataclasses.replace(TRUTH, segment_stiffness=(0.35, 0.12))
    data = synthetic(noise=0.0)
    n = data.sample_index.size
    loads = np.array([[0.0, 0.0, -0.15] if i % 2 else [0.0, 0.0, 0.0] for i in range(n)])
    data = dataclasses.replace(data, loads=loads)
    data = dataclasses.replace(data, tips=predicted_tips(ARM, truth, data)
                               + np.random.default_rng(7).normal(0, 2e-5, (n, 3)))
    fit = identify(ARM, data, UNIT)
    assert fit.plant.segment_stiffness == pytest.approx(truth.segment_stiffness, rel=0.1)
    assert fit.plant.tip_force == pytest.approx(truth.tip_force, abs=0.01)
    assert "segment_stiffness[1]" in fit.std_errors
    assert not any(note.startswith("tip_force ~ segment_stiffness") for note in fit.not_separable)
    unloaded = identify(ARM, dataclasses.replace(data, loads=None), UNIT)  # the same tips, the load not known
    assert "segment_stiffness[0]" not in unloaded.values and unloaded.rms_m > 2 * fit.rms_m
