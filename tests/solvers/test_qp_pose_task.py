"""The qp controller's pose task: orientation feedback on SO(3) (full, and axis only for a sleeve
whose roll is unknown), limits kept, and the paper controller refusing an orientation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from tests import old_defaults
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import psi_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.models.so3 import angle_between, axis_angle_between, rotation_error
from wristmark.solvers.controller import ControllerConfig, OrientationTask
from wristmark.solvers.controller_registry import make_controller

P = RobotParams()
HOME = np.array(HOME_PSI)
DT = 0.06


def _pose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    T = forward_kinematics(P, q).T_world_tip
    return T[:3, 3].copy(), T[:3, :3].copy()


def _run(R_des: np.ndarray, axis_only: bool, steps: int = 40, **cfg: float) -> tuple[list, list, list, np.ndarray]:
    """Closed loop on the nominal model: measured pose = model pose; position target = start."""
    c = make_controller(P, old_defaults.controller(kind="qp", **cfg))
    q = HOME.copy()
    p0, _ = _pose(q)
    angles, axes, pos = [], [], []
    lo, hi = psi_bounds(P)
    for _ in range(steps):
        p, R = _pose(q)
        angles.append(angle_between(R_des, R))
        axes.append(axis_angle_between(R_des[:, 2], R[:, 2]))
        pos.append(float(np.linalg.norm(p - p0)))
        step = c.step(q, p, p0, np.zeros(3), DT, OrientationTask(R_des, np.zeros(3), R, axis_only=axis_only))
        assert np.all(step.psi_next >= lo - 1e-12) and np.all(step.psi_next <= hi + 1e-12)
        assert np.all(np.abs(step.psi_dot) <= np.asarray(P.max_velocity) + 1e-9)
        q = step.psi_next
    return angles, axes, pos, q


def test_orientation_error_decays_and_the_position_is_kept() -> None:
    _, R0 = _pose(HOME)
    R_des = Rotation.from_rotvec(np.deg2rad([3.0, -2.0, 4.0])).as_matrix() @ R0
    angles, _, pos, _ = _run(R_des, axis_only=False)
    big = [a for a in angles if a > np.deg2rad(0.01)]
    assert all(b < a for a, b in zip(big, big[1:])), np.rad2deg(angles)
    assert angles[-1] < np.deg2rad(0.01)
    assert max(pos) < 0.5e-3 and pos[-1] < 1e-5  # the tip stays put while the tool turns


def test_orientation_speed_is_capped() -> None:
    """A large error turns the tool at max_angular_speed, not faster."""
    _, R0 = _pose(HOME)
    R_des = Rotation.from_rotvec(np.deg2rad([0.0, 20.0, 0.0])).as_matrix() @ R0
    angles, _, _, _ = _run(R_des, axis_only=False, steps=4, max_angular_speed=0.1)
    rates = -np.diff(angles) / DT
    assert np.all(rates <= 0.1 + 1e-3) and np.all(rates > 0.08), rates


def test_axis_only_turns_the_axis_and_leaves_the_roll() -> None:
    """Roll unknown (reference sleeve): a desired frame that differs by a tilt of the axis and a
    roll about it; the axis is steered onto the desired one, the roll is not chased."""
    _, R0 = _pose(HOME)
    z = R0[:, 2]
    tilt = Rotation.from_rotvec(np.deg2rad(3.0) * np.cross(z, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(z, [0, 0, 1])))
    R_des = tilt.as_matrix() @ R0 @ Rotation.from_rotvec([0.0, 0.0, np.deg2rad(10.0)]).as_matrix()
    angles, axes, _, q = _run(R_des, axis_only=True)
    assert axes[-1] < np.deg2rad(0.01) < axes[0]
    _, R_end = _pose(q)
    roll_left = abs(float(rotation_error(R_des, R_end) @ R_end[:, 2]))  # about the axis
    assert roll_left > np.deg2rad(8.0)  # most of the 10 deg roll remains: only damped, never steered
    full = _run(R_des, axis_only=False)[0]
    assert full[-1] < np.deg2rad(0.05) < angles[-1]  # the full task would have turned it


def test_paper_controller_refuses_an_orientation() -> None:
    c = make_controller(P, old_defaults.controller(kind="paper"))
    p, R = _pose(HOME)
    with pytest.raises(ConfigError, match="position-only"):
        c.step(HOME, p, p, None, DT, OrientationTask(R, np.zeros(3), R))


def test_without_a_task_the_qp_is_unchanged_by_the_pose_settings() -> None:
    """Position only, the pose task's own settings do not enter the step."""
    p, _ = _pose(HOME)
    a = make_controller(P, old_defaults.controller(kind="qp")).step(HOME, p, p + [0.002, 0, 0], None, DT)
    b = make_controller(P, old_defaults.controller(kind="qp", kr=40.0, pose_orientation_weight=1.0,
                                                   max_angular_speed=2.0)).step(HOME, p, p + [0.002, 0, 0], None, DT)
    np.testing.assert_array_equal(a.psi_next, b.psi_next)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(st.floats(-1, 1), min_size=6, max_size=6), st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
       st.booleans())
def test_pose_task_keeps_the_limits(u: list[float], rv: list[float], axis_only: bool) -> None:
    lo, hi = psi_bounds(P)
    span_lo = np.where(np.isfinite(lo), lo, -np.pi)
    span_hi = np.where(np.isfinite(hi), hi, np.pi)
    q = span_lo + (np.asarray(u) + 1) / 2 * (span_hi - span_lo)
    p, R = _pose(q)
    R_des = Rotation.from_rotvec(rv).as_matrix() @ R
    c = make_controller(P, old_defaults.controller(kind="qp", kr=50.0, max_angular_speed=5.0))
    step = c.step(q, p, p + 0.01, np.zeros(3), DT, OrientationTask(R_des, np.asarray(rv), R, axis_only))
    assert np.all(step.psi_next >= lo - 1e-12) and np.all(step.psi_next <= hi + 1e-12)
    assert np.all(np.abs(step.psi_dot) <= np.asarray(P.max_velocity) + 1e-9)


@pytest.mark.parametrize("key", ["kr", "pose_orientation_weight"])
def test_negative_pose_settings_are_refused(key: str) -> None:
    with pytest.raises(ConfigError, match=key):
        ControllerConfig(**{key: -1.0}).validate()  # type: ignore[arg-type]
