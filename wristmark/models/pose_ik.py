"""Nominal tip-pose inverse kinematics: the configuration whose tip frame has a given position
and orientation (6 tasks, 6 joints), for the open loop of an orientation-holding trajectory.

Solved with scipy's bounded trust-region least squares on the residual
r(psi) = [p_target - p(psi); s log(R_target R(psi)^T)], s = ``orientation_scale`` [m/rad]
(one radian of orientation error weighs like s metres of position), with the 6x6 tip
Jacobian (exact at r = 0) as its Jacobian; phi, d and the bending angles stay in their limits,
the bending-plane angles are free and wrapped afterwards (models.limits.clamp_psi).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from wristmark.models.arm_spec import Arm, arm_size
from wristmark.models.errors import InputError
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import check_psi, forward_kinematics, tip_jacobian
from wristmark.models.limits import clamp_psi, psi_bounds
from wristmark.models.so3 import rotation_error

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PoseIkResult:
    """psi [rad, m, rad x4] within limits; position_error [m] and orientation_error [rad] left."""

    psi: Array
    position_error: float
    orientation_error: float


def solve_pose_ik(params: Arm, p_world_target: object, R_world_target: object, psi_start: object,
                  orientation_scale: float = 0.03, tol: float = 1e-10) -> PoseIkResult:
    """Configuration whose nominal tip is at ``p_world_target`` (3,) [m] with the tip frame's
    orientation ``R_world_target`` (3x3), both in {w}; starts from ``psi_start``. An unreachable
    pose returns the best compromise (see the errors)."""
    p = np.asarray(p_world_target, float)
    R = np.asarray(R_world_target, float)
    if p.shape != (3,) or R.shape != (3, 3) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(R))):
        raise InputError(f"pose IK needs a finite position (3,) [m] and rotation (3, 3), got {p.shape} and {R.shape}")
    s = float(orientation_scale)
    lo, hi = psi_bounds(params)
    q0 = np.clip(clamp_psi(params, check_psi(psi_start, params)), lo, hi)

    def residual(q: Array) -> Array:
        f = forward_kinematics(params, q)
        return np.concatenate([p - f.tip, s * rotation_error(R, f.T_world_tip[:3, :3])])

    def jacobian(q: Array) -> Array:
        J = tip_jacobian(params, q)
        return -np.vstack([J[:3], s * J[3:]])

    sol = least_squares(residual, q0, jac=jacobian, bounds=(lo, hi), method="trf", xtol=tol, ftol=tol, gtol=tol,
                        max_nfev=50)
    q = clamp_psi(params, sol.x)
    r = residual(q)
    return PoseIkResult(q, float(np.linalg.norm(r[:3])), float(np.linalg.norm(r[3:]) / s))


def nominal_ik(params: Arm, p_world: Array, R_world: Array | None, psi_start: Array) -> Array:
    """The open loop's command: position IK of the tip ``p_world`` [m] in {w}, or pose IK when a
    tip-frame orientation ``R_world`` (3x3, {w}) is asked for too. An arm of fewer than 6
    configuration variables cannot hold a pose: position only (the orientation is dropped)."""
    if R_world is None or arm_size(params)[0] < 6:
        return solve_tip_ik(params, p_world, psi_start).psi
    return solve_pose_ik(params, p_world, R_world, psi_start).psi
