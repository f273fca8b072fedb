"""Pose IK (the open loop of an orientation-holding path): reaches a reachable tip pose exactly,
within the joint limits, and refuses malformed targets."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wristmark.models.errors import InputError
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import psi_bounds
from wristmark.models.pose_ik import nominal_ik, solve_pose_ik
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.models.so3 import angle_between

P = RobotParams()
HOME = np.array(HOME_PSI)


@pytest.mark.parametrize("seed", range(5))
def test_reaches_a_nearby_pose(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q_true = HOME + rng.uniform(-0.15, 0.15, 6) * np.array([1, 0.1, 1, 1, 1, 1])
    T = forward_kinematics(P, q_true).T_world_tip
    res = solve_pose_ik(P, T[:3, 3], T[:3, :3], HOME)
    T_got = forward_kinematics(P, res.psi).T_world_tip
    assert np.linalg.norm(T_got[:3, 3] - T[:3, 3]) < 1e-8 and res.position_error < 1e-8
    assert angle_between(T_got[:3, :3], T[:3, :3]) < 1e-8
    lo, hi = psi_bounds(P)
    assert np.all(res.psi >= lo) and np.all(res.psi <= hi)


def test_holds_an_orientation_where_position_ik_would_turn_the_tool() -> None:
    T0 = forward_kinematics(P, HOME).T_world_tip
    p = T0[:3, 3] + [0.01, -0.005, 0.01]
    q_pos = nominal_ik(P, p, None, HOME)
    q_pose = nominal_ik(P, p, T0[:3, :3], HOME)
    assert angle_between(forward_kinematics(P, q_pos).T_world_tip[:3, :3], T0[:3, :3]) > np.deg2rad(1.0)
    T = forward_kinematics(P, q_pose).T_world_tip
    assert angle_between(T[:3, :3], T0[:3, :3]) < 1e-8 and np.linalg.norm(T[:3, 3] - p) < 1e-8


def test_unreachable_pose_reports_its_errors() -> None:
    T0 = forward_kinematics(P, HOME).T_world_tip
    R = Rotation.from_rotvec([0.3, 0, 0]).as_matrix() @ T0[:3, :3]
    far = T0[:3, 3] + [0.0, 0.0, 0.5]  # half a metre beyond the stem's feed
    res = solve_pose_ik(P, far, R, HOME)
    assert res.position_error > 0.1
    T = forward_kinematics(P, res.psi).T_world_tip
    assert res.position_error == pytest.approx(float(np.linalg.norm(T[:3, 3] - far)))
    assert res.orientation_error == pytest.approx(angle_between(T[:3, :3], R), abs=1e-9)


def test_malformed_target_is_refused() -> None:
    with pytest.raises(InputError, match="rotation"):
        solve_pose_ik(P, [0.0, 0.0, 0.1], np.eye(2), HOME)
