"""Joint and actuator limits: check, clamp, wrap (psi = [phi, d, theta1, delta1, theta2, delta2])."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import LimitError
from wristmark.models.kinematics import check_psi
from wristmark.models.robot_params import RobotParams

Array = NDArray[np.float64]


def wrap_angle(a: float) -> float:
    """Wrap an angle to (-pi, pi] [rad]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


def psi_bounds(params: RobotParams) -> tuple[Array, Array]:
    """Lower and upper bounds of psi. delta has none (it wraps): +-inf."""
    lo = np.array([params.phi_range[0], params.d_range[0], 0.0, -np.inf, 0.0, -np.inf])
    hi = np.array(
        [params.phi_range[1], params.d_range[1], params.theta_max[0], np.inf, params.theta_max[1], np.inf]
    )
    return lo, hi


def normalize_psi(psi: object) -> Array:
    """Canonical psi: theta >= 0 (a negative bend flips the plane by pi), deltas wrapped."""
    q = check_psi(psi).copy()
    for t in (2, 4):
        if q[t] < 0:
            q[t] = -q[t]
            q[t + 1] += math.pi
        q[t + 1] = wrap_angle(q[t + 1])
    return q


def clamp_psi(params: RobotParams, psi: object) -> Array:
    """Normalize psi [rad, m, rad, rad, rad, rad] and clamp it into the joint limits of ``params``."""
    q = normalize_psi(psi)
    lo, hi = psi_bounds(params)
    return np.clip(q, lo, hi)


def within_limits(params: RobotParams, psi: object, tol: float = 1e-12) -> bool:
    """True if psi (normalized) lies within the joint limits up to ``tol``."""
    q = normalize_psi(psi)
    lo, hi = psi_bounds(params)
    return bool(np.all(q >= lo - tol) and np.all(q <= hi + tol))


def check_limits(params: RobotParams, psi: object) -> Array:
    """Return normalized psi or raise LimitError naming the first joint out of range."""
    q = normalize_psi(psi)
    lo, hi = psi_bounds(params)
    names = ("phi", "d", "theta1", "delta1", "theta2", "delta2")
    for i in range(6):
        if not lo[i] - 1e-12 <= q[i] <= hi[i] + 1e-12:
            raise LimitError(f"{names[i]} = {q[i]:.6g} is outside [{lo[i]:.6g}, {hi[i]:.6g}]")
    return q


def clamp_velocity(params: RobotParams, psi_dot: object) -> Array:
    """Scale psi_dot [rad/s, m/s, rad/s, ...] uniformly so every component respects max_velocity
    (keeps direction)."""
    v = np.asarray(psi_dot, dtype=float)
    vmax = np.asarray(params.max_velocity)
    ratio = float(np.max(np.abs(v) / vmax))
    return v / ratio if ratio > 1.0 else v.copy()


def actuator_bounds(params: RobotParams) -> tuple[Array, Array]:
    """Box bounds of the actuator coordinates [rad, m, m, m, m, m] implied by the joint limits."""
    r1, r2 = params.backbone_radius
    s1 = r1 * params.theta_max[0]
    s2 = r2 * params.theta_max[1]
    lo = np.array([params.phi_range[0], params.d_range[0], -s1, -s1, -s2, -s2])
    hi = np.array([params.phi_range[1], params.d_range[1], s1, s1, s2, s2])
    return lo, hi
