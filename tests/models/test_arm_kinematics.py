"""models.arm_kinematics: any arm's frames and 6 x n tip Jacobian.

The reference arm (format 1 and configs/robots/paper.yaml) against today's models.kinematics to
1e-12; the Jacobian against finite differences for random arms; planar segments against the same
arm with the plane as a configuration; an empty stem; the batch path against the one-psi path.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.models.arm_strategies import psis, robot_files, spec_of
from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian, arm_tip_position, f_g_array
from wristmark.models.arm_spec import ArmSpec, Segment, StemJoint, load_arm
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.constant_curvature import f_g
from wristmark.models.errors import InputError
from wristmark.models.kinematics import forward_kinematics, tip_jacobian
from wristmark.models.robot_params import RobotParams
from wristmark_testing.reference_chain import chain

PARAMS = RobotParams()
REFERENCE = {"format 1": ArmSpec.from_params(PARAMS), "paper.yaml": load_arm(CONFIG_DIR / "robots" / "paper.yaml")}
SEEDED = settings(max_examples=60, derandomize=True, deadline=None,
                  suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _reference_psis(count: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.uniform([-math.pi, 0, 0, -math.pi, 0, -math.pi], [math.pi, 0.15, math.pi / 2, math.pi, 2.09, math.pi],
                    (count, 6))
    q[:5, 2] = [0.0, 1e-9, 0.05, 0.19999, 0.2]  # the series and its switch
    q[5:10, 4] = [0.0, 1e-9, 0.05, 0.19999, 0.2]
    return q


@pytest.mark.parametrize("which", sorted(REFERENCE))
def test_the_reference_arm_equals_todays_chain(which: str) -> None:
    spec = REFERENCE[which]
    batch = _reference_psis(200)
    poses_b = arm_frames(spec, batch)
    J_b = arm_tip_jacobian(spec, batch, poses_b)
    for k, psi in enumerate(batch):
        ref = forward_kinematics(PARAMS, psi)
        J_ref = tip_jacobian(PARAMS, psi, ref)
        base = (ref.T_world_1b, ref.T_world_2b)
        end = (ref.T_world_1e, ref.T_world_2e)
        for poses, J in ((arm_frames(spec, psi), arm_tip_jacobian(spec, psi)), (None, J_b[k])):
            np.testing.assert_allclose(J, J_ref, rtol=0, atol=1e-12)
            got = poses if poses is not None else None
            if got is None:
                continue
            np.testing.assert_allclose(got.T_world_tip, ref.T_world_tip, rtol=0, atol=1e-12)
            np.testing.assert_allclose(got.T_world_marker, ref.T_world_marker, rtol=0, atol=1e-12)
            np.testing.assert_allclose(got.T_world_base, base, rtol=0, atol=1e-12)
            np.testing.assert_allclose(got.T_world_end, end, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses_b.T_world_tip[k], ref.T_world_tip, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses_b.T_world_marker[k], ref.T_world_marker, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses_b.T_world_base[k], base, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses_b.T_world_end[k], end, rtol=0, atol=1e-12)


def test_the_reference_arm_matches_the_independent_chain() -> None:
    spec = REFERENCE["paper.yaml"]
    for psi in _reference_psis(20, seed=2):
        ref = chain({"L1": 0.1, "L2": 0.02, "Lr": 0.01, "lm": 0.005, "lt": 0.015}, psi)
        got = arm_frames(spec, psi)
        np.testing.assert_allclose(got.T_world_tip, ref["tip"], rtol=0, atol=1e-14)
        np.testing.assert_allclose(got.T_world_marker, ref["marker"], rtol=0, atol=1e-14)


def test_vectorised_f_g_matches_the_scalar() -> None:
    t = np.concatenate([np.linspace(-3.2, 3.2, 641), [0.0, 1e-300, -1e-12, 0.19999999, 0.2, -0.2]])
    got = np.array(f_g_array(t)).T
    want = np.array([f_g(x) for x in t.tolist()])
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-16)


def _rotation_rate(R_plus: np.ndarray, R_minus: np.ndarray, R: np.ndarray, h: float) -> np.ndarray:
    W = (R_plus - R_minus) / (2 * h) @ R.T
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2


def _finite_difference_jacobian(spec: ArmSpec, psi: np.ndarray, h: float = 1e-6) -> np.ndarray:
    T = arm_frames(spec, psi).T_world_tip
    J = np.zeros((6, spec.n))
    for i in range(spec.n):
        e = np.zeros(spec.n)
        e[i] = h
        Tp, Tm = arm_frames(spec, psi + e).T_world_tip, arm_frames(spec, psi - e).T_world_tip
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        J[3:, i] = _rotation_rate(Tp[:3, :3], Tm[:3, :3], T[:3, :3], h)
    return J


@SEEDED
@given(data=st.data(), robot=robot_files())
def test_jacobian_matches_finite_differences_for_random_arms(tmp_path: Path, data: st.DataObject,
                                                             robot: dict) -> None:  # type: ignore[type-arg]
    spec = spec_of(robot, tmp_path)
    psi = data.draw(psis(spec))
    J = arm_tip_jacobian(spec, psi)
    assert J.shape == (6, spec.n)
    np.testing.assert_allclose(J, _finite_difference_jacobian(spec, psi), rtol=0, atol=2e-7)
    # the one-psi and the batch paths agree
    batch = np.stack([psi, psi])
    poses = arm_frames(spec, batch)
    one = arm_frames(spec, psi)
    for name in ("T_world_base", "T_world_end", "T_world_marker", "T_world_tip"):
        np.testing.assert_allclose(getattr(poses, name)[1], getattr(one, name), rtol=0, atol=1e-15)
    np.testing.assert_allclose(arm_tip_jacobian(spec, batch)[0], J, rtol=0, atol=1e-15)
    np.testing.assert_allclose(arm_tip_position(spec, psi), one.tip, rtol=0, atol=0)
    # frames are rigid transforms; consecutive rings are a spacer apart
    for T in (*one.T_world_base, *one.T_world_end, one.T_world_marker, one.T_world_tip):
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-14)
        np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    for t in range(1, len(spec.segments)):
        gap = np.linalg.norm(one.T_world_base[t][:3, 3] - one.T_world_end[t - 1][:3, 3])
        assert gap == pytest.approx(spec.segments[t].spacer, abs=1e-15)


def _as_bending(spec: ArmSpec) -> ArmSpec:
    """The same arm with every planar segment's plane as a configuration variable."""
    segs = tuple(replace(s, planar=None, max_velocity=(*s.max_velocity, 1.0)) if s.planar is not None else s
                 for s in spec.segments)
    return replace(spec, segments=segs)


@pytest.mark.parametrize("theta", [-1.2, -1e-9, 0.0, 0.15, 0.9])
def test_a_planar_segment_is_a_bending_one_at_its_fixed_plane(theta: float) -> None:
    planar = load_arm(CONFIG_DIR / "robots" / "planar.yaml")
    free = _as_bending(planar)
    psi = np.array([0.4, 0.03, theta, -0.7 * theta])
    # free: phi, d, theta1, delta1, theta2, delta2 with the planes 0 and pi/2
    psi_free = np.array([0.4, 0.03, theta, 0.0, -0.7 * theta, math.pi / 2])
    a, b = arm_frames(planar, psi), arm_frames(free, psi_free)
    np.testing.assert_allclose(a.T_world_tip, b.T_world_tip, rtol=0, atol=1e-15)
    J, Jf = arm_tip_jacobian(planar, psi), arm_tip_jacobian(free, psi_free)
    np.testing.assert_allclose(J, Jf[:, [0, 1, 2, 4]], rtol=0, atol=1e-15)
    if theta:  # a planar segment bends only in its plane: x_1b-z_1b for segment 1
        seg1 = arm_frames(planar, np.array([0.0, 0.0, theta, 0.0])).T_world_end[0]
        assert seg1[1, 3] == pytest.approx(0.0, abs=1e-18) and seg1[0, 3] * theta > 0


def test_an_empty_stem_is_the_stem_at_zero() -> None:
    paper = REFERENCE["paper.yaml"]
    bare = replace(paper, stem=(), home=None)
    bare.validate()
    assert bare.n == 4
    psi = np.array([0.8, -2.0, 1.3, 0.4])
    full = np.concatenate([[0.0, 0.0], psi])
    np.testing.assert_allclose(arm_frames(bare, psi).T_world_tip, arm_frames(paper, full).T_world_tip, atol=0)
    np.testing.assert_allclose(arm_tip_jacobian(bare, psi), arm_tip_jacobian(paper, full)[:, 2:], atol=0)


def test_stem_joints_act_along_z_in_any_order() -> None:
    paper = REFERENCE["paper.yaml"]
    phi, d = paper.stem
    spun = replace(paper, stem=(replace(d, name="d0"), replace(phi, name="a"), phi, d))
    psi = np.array([0.2, 0.3, 0.1, 0.05, 1.0, 0.5, 0.7, -1.0])
    same = np.array([0.4, 0.25, 1.0, 0.5, 0.7, -1.0])
    np.testing.assert_allclose(arm_frames(spun, psi).T_world_tip, arm_frames(paper, same).T_world_tip, atol=1e-15)
    J = arm_tip_jacobian(spun, psi)
    np.testing.assert_array_equal(J[:, 1], J[:, 2])  # two revolute joints
    np.testing.assert_array_equal(J[:, 0], J[:, 3])  # two prismatic joints
    np.testing.assert_allclose(J[:, 1], arm_tip_jacobian(paper, same)[:, 0], atol=1e-15)


def test_a_single_segment_arm_straight_and_bent() -> None:
    seg = Segment(length=0.04, theta_max=math.pi, max_velocity=(1.0, 1.0),
                  actuation=REFERENCE["paper.yaml"].segments[0].actuation)
    spec = ArmSpec(segments=(seg,), stem=(StemJoint("prismatic_z", "d", (0.0, 0.1), 0.01),), marker_offset=0.005,
                   tip_offset=0.015)
    spec.validate()
    np.testing.assert_allclose(arm_tip_position(spec, [0.01, 0.0, 0.3]), [0, 0, 0.07], atol=1e-17)
    # a half circle in the plane delta = 0 bends towards +x: the end ring lies 2 L/pi from the axis
    end = arm_frames(spec, [0.0, math.pi, 0.0]).T_world_end[0]
    np.testing.assert_allclose(end[:3, 3], [2 * 0.04 / math.pi, 0, 0], atol=1e-17)
    np.testing.assert_allclose(end[:3, 2], [0, 0, -1], atol=1e-15)


@pytest.mark.parametrize("bad, words", [([0.0] * 5, "6 entries"), ([0, 0, math.nan, 0, 0, 0], "finite"),
                                        (0.0, "6 entries"), ([[0.0] * 7], "6 entries")])
def test_bad_psi_is_an_input_error(bad: object, words: str) -> None:
    with pytest.raises(InputError, match=words):
        arm_frames(REFERENCE["paper.yaml"], bad)
    with pytest.raises(InputError, match=words):
        arm_tip_jacobian(REFERENCE["paper.yaml"], bad)
