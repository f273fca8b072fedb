"""Pinocchio model vs the closed form: frames and the 6x6 Jacobian to 1e-9 for every N."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.models.errors import InputError
from wristmark.models.kinematics import forward_kinematics, tip_jacobian
from wristmark.models.pinocchio_model import PinocchioArm
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.models.urdf import FRAME_NAMES

PARAMS = RobotParams()
SEEDED = settings(max_examples=40, derandomize=True, deadline=None)
LINKS = [1, 2, 5, 8]
ATTR = dict(
    zip(
        FRAME_NAMES,
        ("T_world_1b", "T_world_1e", "T_world_2b", "T_world_2e", "T_world_marker", "T_world_tip"),
    )
)


@cache
def arm(n: int) -> PinocchioArm:
    return PinocchioArm(PARAMS, n)


def _theta(tmax: float) -> st.SearchStrategy[float]:
    return st.one_of(st.floats(0.0, tmax), st.sampled_from([0.0, 1e-10, tmax]))


psis = st.tuples(
    st.floats(-math.pi, math.pi),
    st.floats(0.0, 0.15),
    _theta(PARAMS.theta_max[0]),
    st.floats(-math.pi, math.pi),
    _theta(PARAMS.theta_max[1]),
    st.floats(-math.pi, math.pi),
).map(np.array)


@pytest.mark.parametrize("n", LINKS)
@SEEDED
@given(psi=psis)
def test_frames_and_jacobian_agree_with_closed_form(n: int, psi: np.ndarray) -> None:
    a = arm(n)
    got = a.forward(psi)
    ref = forward_kinematics(PARAMS, psi)
    for name, attr in ATTR.items():
        T, R = getattr(got, attr), getattr(ref, attr)
        np.testing.assert_allclose(T[:3, 3], R[:3, 3], rtol=0, atol=1e-9)  # [m]
        np.testing.assert_allclose(T[:3, :3], R[:3, :3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.frame_pose(name, psi), T, rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.tip_jacobian(psi), tip_jacobian(PARAMS, psi), rtol=0, atol=1e-9)


@pytest.mark.parametrize("n", [1, 3])
@SEEDED
@given(psi=psis)
def test_dq_dpsi_vs_central_differences(n: int, psi: np.ndarray) -> None:
    a = arm(n)
    h = 1e-6
    D = a.dq_dpsi(psi)
    assert D.shape == (a.model.nq, 6)
    Dfd = np.column_stack(
        [(a.q_from_psi(psi + h * e) - a.q_from_psi(psi - h * e)) / (2 * h) for e in np.eye(6)]
    )
    np.testing.assert_allclose(D, Dfd, rtol=0, atol=1e-9)


def test_q_at_straight_arm_has_nominal_chords() -> None:
    a = arm(5)
    q = a.q_from_psi([0.2, 0.03, 0.0, 0.4, 0.0, -0.1])
    m = a.model
    for t, L in ((1, PARAMS.segment_lengths[0]), (2, PARAMS.segment_lengths[1])):
        for k in range(1, 6):
            assert q[m.idx_qs[m.getJointId(f"seg{t}_chord_{k}")]] == L / 5
        assert q[m.idx_qs[m.getJointId(f"seg{t}_bend_0")]] == 0.0
    assert q[m.idx_qs[m.getJointId("phi")]] == 0.2
    assert q[m.idx_qs[m.getJointId("seg1_plane_in")]] == -0.4
    assert q[m.idx_qs[m.getJointId("seg1_plane_out")]] == 0.4


def test_bend_angles_sum_to_theta() -> None:
    a = arm(8)
    q = a.q_from_psi([0, 0.05, 1.2, 0.0, 0.9, 0.0])
    m = a.model
    s1 = sum(q[m.idx_qs[m.getJointId(f"seg1_bend_{k}")]] for k in range(9))
    assert s1 == pytest.approx(1.2, rel=1e-15)


def test_models_for_the_viewer() -> None:
    a = arm(2)
    assert isinstance(a.model, pin.Model) and isinstance(a.data, pin.Data)
    assert a.visual_model.ngeoms == 2 * 2 + 7
    assert a.collision_model.ngeoms > 0
    assert "<robot" in a.urdf
    # the geometry placements follow the arm: sleeve centre at the marker frame
    q = a.q_from_psi(HOME_PSI)
    vdata = pin.GeometryData(a.visual_model)
    pin.updateGeometryPlacements(a.model, a.data, a.visual_model, vdata, q)
    gid = a.visual_model.getGeometryId("marker_0")
    np.testing.assert_allclose(
        vdata.oMg[gid].translation,
        forward_kinematics(PARAMS, HOME_PSI).T_world_marker[:3, 3],
        atol=1e-12,
    )


def test_unknown_frame_and_bad_psi() -> None:
    a = arm(1)
    with pytest.raises(InputError, match="unknown frame 'wrist'"):
        a.frame_pose("wrist", HOME_PSI)
    with pytest.raises(InputError, match="finite"):
        a.tip_jacobian([0, 0, math.nan, 0, 0, 0])
    # any URDF link works as a frame too
    assert a.frame_pose("seg1_link_0", HOME_PSI).shape == (4, 4)


def test_link_cylinders_follow_the_arc() -> None:
    """Each pseudo-rigid link's cylinder centre lies on its chord, within the sagitta of the arc."""
    from wristmark.models.constant_curvature import segment_point

    n = 8
    a = arm(n)
    psi = np.array(HOME_PSI)
    vdata = pin.GeometryData(a.visual_model)
    pin.updateGeometryPlacements(a.model, a.data, a.visual_model, vdata, a.q_from_psi(psi))
    fr = forward_kinematics(PARAMS, psi)
    for t, T_base in ((1, fr.T_world_1b), (2, fr.T_world_2b)):
        L, th, de = PARAMS.segment_lengths[t - 1], psi[2 * t], psi[2 * t + 1]
        sagitta = L / th * (1 - math.cos(th / (2 * n)))  # [m]
        for k in range(n):
            g = vdata.oMg[a.visual_model.getGeometryId(f"seg{t}_link_{k}_0")]
            mid = T_base[:3, :3] @ segment_point(L, th, de, (k + 0.5) / n) + T_base[:3, 3]
            gap = np.linalg.norm(g.translation - mid)
            assert sagitta * 0.99 < gap < sagitta * 1.01 + 1e-9
