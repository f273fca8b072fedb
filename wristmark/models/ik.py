"""Nominal tip-position inverse kinematics: damped least squares on the closed-form Jacobian.

Gives the open-loop commands (the configuration the *model* says puts the tip at a target).
The arm has 6 DOF for a 3D task; each step is the damped minimum-norm solution
dq = J^T (J J^T + lambda^2 I)^-1 e with J the 3x6 linear rows of the tip Jacobian, so from a
nearby start the solution stays close to the start (smooth along a path). Every iterate is
normalised and clamped into the joint limits (models.limits.clamp_psi); the damping adapts
(Levenberg-Marquardt style: a step that does not reduce the error is retried with more damping).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm
from wristmark.models.errors import InputError
from wristmark.models.kinematics import check_psi, forward_kinematics, tip_jacobian
from wristmark.models.limits import clamp_psi

Array = NDArray[np.float64]


@dataclass(frozen=True)
class IkResult:
    """Result of :func:`solve_tip_ik`.

    psi: configuration [rad, m, rad, rad, rad, rad] (normalised, within limits).
    error: |tip(psi) - target| [m]. iterations: steps taken. converged: error <= tol.
    """

    psi: Array
    error: float
    iterations: int
    converged: bool


def _tip_error(params: Arm, q: Array, target: Array) -> tuple[Array, Array]:
    frames = forward_kinematics(params, q)
    e = target - frames.tip
    J = tip_jacobian(params, q, frames)[:3]
    return e, J


def solve_tip_ik(
    params: Arm,
    p_world_target: object,
    psi_start: object,
    tol: float = 1e-7,
    max_iter: int = 60,
    damping: float = 1e-4,
    max_step: float = 0.2,
) -> IkResult:
    """Configuration whose nominal tip is at ``p_world_target`` (3,) in {w} [m].

    Starts from ``psi_start``; stops when the error is <= ``tol`` [m] or after ``max_iter``
    steps. ``damping`` is the initial lambda [m]; ``max_step`` bounds |dq| per step. An
    unreachable target returns the closest point found with ``converged=False``.
    """
    try:
        target = np.asarray(p_world_target, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"IK target must be 3 numbers [m] in {{w}}, got {p_world_target!r}") from exc
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise InputError(f"IK target must be 3 finite numbers [m] in {{w}}, got {target.tolist()}")
    q = clamp_psi(params, check_psi(psi_start, params))
    e, J = _tip_error(params, q, target)
    err = float(np.linalg.norm(e))
    lam = damping
    it = 0
    while err > tol and it < max_iter:
        it += 1
        while True:
            A = J @ J.T + (lam * lam) * np.eye(3)
            dq = J.T @ np.linalg.solve(A, e)
            n = float(np.linalg.norm(dq))
            if n > max_step:
                dq *= max_step / n
            q_new = clamp_psi(params, q + dq)
            e_new, J_new = _tip_error(params, q_new, target)
            err_new = float(np.linalg.norm(e_new))
            if err_new < err:
                q, e, J, err = q_new, e_new, J_new, err_new
                lam = max(lam * 0.3, 1e-9)
                break
            lam *= 10.0
            if lam > 1e3:
                return IkResult(q, err, it, err <= tol)
    return IkResult(q, err, it, err <= tol)
