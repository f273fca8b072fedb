"""Closed-form chain vs an independent 4x4 implementation of docs/design.md; Jacobian vs FD."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from wristmark.models.errors import InputError
from wristmark.models.kinematics import (
    ArmFrames,
    check_psi,
    forward_kinematics,
    tip_jacobian,
    tip_position,
)
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark_testing.reference_chain import chain

PARAMS = RobotParams()
SEEDED = settings(max_examples=60, derandomize=True, deadline=None)
NAMES = {
    "1b": "T_world_1b",
    "1e": "T_world_1e",
    "2b": "T_world_2b",
    "2e": "T_world_2e",
    "marker": "T_world_marker",
    "tip": "T_world_tip",
}


def lengths_of(p: RobotParams) -> dict[str, float]:
    return {
        "L1": p.segment_lengths[0],
        "L2": p.segment_lengths[1],
        "Lr": p.rigid_length,
        "lm": p.marker_offset,
        "lt": p.tip_offset,
    }


def _theta(tmax: float) -> st.SearchStrategy[float]:
    return st.one_of(st.floats(0.0, tmax), st.sampled_from([0.0, 1e-10, 1e-6, 0.2, tmax]))


psis = st.tuples(
    st.one_of(st.floats(-math.pi, math.pi), st.sampled_from([-math.pi, math.pi])),
    st.one_of(st.floats(0.0, 0.15), st.sampled_from([0.0, 0.15])),
    _theta(PARAMS.theta_max[0]),
    st.floats(-math.pi, math.pi),
    _theta(PARAMS.theta_max[1]),
    st.floats(-math.pi, math.pi),
).map(np.array)


@SEEDED
@given(psis)
def test_frames_match_independent_chain(psi: np.ndarray) -> None:
    fr = forward_kinematics(PARAMS, psi)
    ref = chain(lengths_of(PARAMS), psi)
    for key, attr in NAMES.items():
        T = getattr(fr, attr)
        assert T.shape == (4, 4)
        np.testing.assert_allclose(T[:3, 3], ref[key][:3, 3], rtol=0, atol=1e-15)  # [m]
        np.testing.assert_allclose(T[:3, :3], ref[key][:3, :3], rtol=0, atol=1e-14)
        np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    np.testing.assert_array_equal(fr.tip, fr.T_world_tip[:3, 3])
    np.testing.assert_array_equal(tip_position(PARAMS, psi), fr.tip)


@SEEDED
@given(psis, st.one_of(st.floats(-0.5, 0.5), st.sampled_from([1e-9, 0.3])))
def test_bent_stem_matches_independent_chain(psi: np.ndarray, bend: float) -> None:
    """The chain the simulated arm and the viewer use: the stem bent by ``stem_bend``."""
    fr = forward_kinematics(PARAMS, psi, stem_bend=bend)
    ref = chain(lengths_of(PARAMS), psi, stem_bend=bend)
    for key, attr in NAMES.items():
        np.testing.assert_allclose(getattr(fr, attr), ref[key], rtol=0, atol=1e-14)


def test_other_robot_geometry_matches_independent_chain() -> None:
    p = RobotParams(
        segment_lengths=(0.07, 0.031), rigid_length=0.0, marker_offset=0.011, tip_offset=0.0
    )
    psi = np.array([0.3, 0.02, 1.1, -2.0, 0.4, 2.9])
    fr = forward_kinematics(p, psi)
    ref = chain(lengths_of(p), psi)
    for key, attr in NAMES.items():
        np.testing.assert_allclose(getattr(fr, attr), ref[key], rtol=0, atol=1e-15)


def test_straight_arm_tip_lies_on_the_stem_axis() -> None:
    fr = forward_kinematics(PARAMS, [0.4, 0.03, 0.0, 1.0, 0.0, -2.0])
    total = 0.03 + sum(PARAMS.segment_lengths) + PARAMS.rigid_length + PARAMS.marker_offset
    np.testing.assert_allclose(fr.T_world_marker[:3, 3], [0, 0, total], atol=1e-15)
    np.testing.assert_allclose(fr.tip, [0, 0, total + PARAMS.tip_offset], atol=1e-15)
    np.testing.assert_allclose(
        fr.T_world_tip[:3, :3],
        [[math.cos(0.4), -math.sin(0.4), 0], [math.sin(0.4), math.cos(0.4), 0], [0, 0, 1]],
        atol=1e-15,
    )


def test_tiny_bend_is_continuous_with_zero_bend() -> None:
    a = forward_kinematics(PARAMS, [0, 0.05, 0.0, 0.3, 0.0, 0.0])
    b = forward_kinematics(PARAMS, [0, 0.05, 1e-10, 0.3, 1e-10, 0.0])
    # first-order change: rotation ~ 2 theta = 2e-10, position ~ theta * lever
    np.testing.assert_allclose(a.T_world_tip, b.T_world_tip, rtol=0, atol=3e-10)
    assert not np.array_equal(a.T_world_tip, b.T_world_tip)


def _fd_columns(psi: np.ndarray, h: float) -> np.ndarray:
    J = np.zeros((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        Tp = forward_kinematics(PARAMS, psi + e).T_world_tip
        Tm = forward_kinematics(PARAMS, psi - e).T_world_tip
        J[:3, j] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        J[3:, j] = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
    return J


@SEEDED
@given(psis)
def test_jacobian_vs_central_differences(psi: np.ndarray) -> None:
    J = tip_jacobian(PARAMS, psi)
    Jfd = _fd_columns(psi, 1e-6)
    # central differences, h = 1e-6: truncation ~h^2 * 0.2 m, rounding ~eps * 0.2 m / h
    np.testing.assert_allclose(J[:3], Jfd[:3], rtol=0, atol=1e-9)  # linear [m/s per unit]
    np.testing.assert_allclose(J[3:], Jfd[3:], rtol=0, atol=1e-8)  # angular [rad/s per unit]
    np.testing.assert_array_equal(J, tip_jacobian(PARAMS, psi, forward_kinematics(PARAMS, psi)))


def test_jacobian_structure_of_stem_columns() -> None:
    psi = np.array(HOME_PSI)
    J = tip_jacobian(PARAMS, psi)
    tip = forward_kinematics(PARAMS, psi).tip
    np.testing.assert_allclose(J[:, 0], [-tip[1], tip[0], 0, 0, 0, 1], atol=1e-15)
    np.testing.assert_array_equal(J[:, 1], [0, 0, 1, 0, 0, 0])


def test_jacobian_at_straight_arm_delta_columns() -> None:
    # at theta = 0 a change of the bending plane moves nothing
    J = tip_jacobian(PARAMS, [0.2, 0.04, 0.0, 0.5, 0.0, -1.0])
    np.testing.assert_allclose(J[:, 3], 0.0, atol=1e-18)
    np.testing.assert_allclose(J[:, 5], 0.0, atol=1e-18)


def test_jacobian_uses_given_frames() -> None:
    psi = np.array(HOME_PSI)
    other = forward_kinematics(PARAMS, psi + 0.1)
    assert not np.allclose(tip_jacobian(PARAMS, psi, other), tip_jacobian(PARAMS, psi))


@pytest.mark.parametrize(
    "bad, words",
    [
        ([0, 0, 0, 0, 0], ["6 entries", "(5,)"]),
        ([[0] * 6], ["6 entries"]),
        ([0, 0, float("nan"), 0, 0, 0], ["finite"]),
        ([0, 0, 0, float("inf"), 0, 0], ["finite"]),
    ],
)
def test_bad_psi_is_rejected_with_its_reason(bad: list, words: list[str]) -> None:
    for fn in (
        check_psi,
        lambda q: forward_kinematics(PARAMS, q),
        lambda q: tip_jacobian(PARAMS, q),
    ):
        with pytest.raises(InputError) as e:
            fn(bad)
        for w in words:
            assert w in str(e.value)
        assert "\n" not in str(e.value)


def test_check_psi_returns_float_copy_semantics() -> None:
    a = check_psi([1, 2, 3, 4, 5, 6])
    assert a.dtype == np.float64 and a.shape == (6,)
    np.testing.assert_array_equal(a, [1, 2, 3, 4, 5, 6])


def test_arm_frames_is_a_dataclass_of_six_poses() -> None:
    fr = forward_kinematics(PARAMS, HOME_PSI)
    assert isinstance(fr, ArmFrames)
    # frames are independent arrays: editing one does not change another
    fr.T_world_1b[0, 3] = 99.0
    assert fr.T_world_1e[0, 3] != 99.0
