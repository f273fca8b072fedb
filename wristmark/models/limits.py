"""Joint and actuator limits: check, clamp, wrap (psi = [phi, d, theta1, delta1, theta2, delta2])."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.errors import LimitError
from wristmark.models.kinematics import check_psi

Array = NDArray[np.float64]


def wrap_angle(a: float) -> float:
    """Wrap an angle to (-pi, pi] [rad]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


def psi_bounds(params: Arm) -> tuple[Array, Array]:
    """Lower and upper bounds of psi. delta has none (it wraps): +-inf."""
    if isinstance(params, ArmSpec):
        return params.bounds()
    lo = np.array([params.phi_range[0], params.d_range[0], 0.0, -np.inf, 0.0, -np.inf])
    hi = np.array(
        [params.phi_range[1], params.d_range[1], params.theta_max[0], np.inf, params.theta_max[1], np.inf]
    )
    return lo, hi


def normalize_psi(psi: object, arm: Arm | None = None) -> Array:
    """Canonical psi: theta >= 0 (a negative bend flips the plane by pi), deltas wrapped (an
    ArmSpec ``arm``: its segments'; a planar theta stays signed)."""
    q = check_psi(psi, arm).copy()
    if isinstance(arm, ArmSpec):
        for ti, di in zip(arm.theta_index, arm.delta_index):
            if di is None:
                continue
            if q[ti] < 0:
                q[ti] = -q[ti]
                q[di] += math.pi
            q[di] = wrap_angle(q[di])
        return q
    for t in (2, 4):
        if q[t] < 0:
            q[t] = -q[t]
            q[t + 1] += math.pi
        q[t + 1] = wrap_angle(q[t + 1])
    return q


def clamp_psi(params: Arm, psi: object) -> Array:
    """Normalize psi [rad, m, rad, rad, rad, rad] and clamp it into the joint limits of ``params``."""
    q = normalize_psi(psi, params)
    lo, hi = psi_bounds(params)
    return np.clip(q, lo, hi)


def within_limits(params: Arm, psi: object, tol: float = 1e-12) -> bool:
    """True if psi (normalized) lies within the joint limits up to ``tol``."""
    q = normalize_psi(psi, params)
    lo, hi = psi_bounds(params)
    return bool(np.all(q >= lo - tol) and np.all(q <= hi + tol))


def check_limits(params: Arm, psi: object) -> Array:
    """Return normalized psi or raise LimitError naming the first joint out of range."""
    q = normalize_psi(psi, params)
    lo, hi = psi_bounds(params)
    names = params.names if isinstance(params, ArmSpec) else ("phi", "d", "theta1", "delta1", "theta2", "delta2")
    for i in range(len(names)):
        if not lo[i] - 1e-12 <= q[i] <= hi[i] + 1e-12:
            raise LimitError(f"{names[i]} = {q[i]:.6g} is outside [{lo[i]:.6g}, {hi[i]:.6g}]")
    return q


def velocity_limits(params: Arm) -> Array:
    """|psi_dot| limits in psi's order [rad/s or m/s]."""
    return params.velocity_limits() if isinstance(params, ArmSpec) else np.asarray(params.max_velocity, float)


def delta_indices(params: Arm) -> tuple[int, ...]:
    """Indices in psi of the bending-plane angles (they wrap): the reference arm's 3, 5."""
    if isinstance(params, ArmSpec):
        return tuple(i for i in params.delta_index if i is not None)
    return (3, 5)


def clamp_velocity(params: Arm, psi_dot: object) -> Array:
    """Scale psi_dot [rad/s, m/s, rad/s, ...] uniformly so every component respects max_velocity
    (keeps direction)."""
    v = np.asarray(psi_dot, dtype=float)
    vmax = velocity_limits(params)
    ratio = float(np.max(np.abs(v) / vmax))
    return v / ratio if ratio > 1.0 else v.copy()


def actuator_bounds(params: Arm) -> tuple[Array, Array]:
    """Box bounds of the actuator coordinates [rad, m, m, m, m, m] implied by the joint limits
    (any arm: the stem ranges, then per actuator +-(its largest pull at the bend limits))."""
    if isinstance(params, ArmSpec):
        return _spec_actuator_bounds(params)
    r1, r2 = params.backbone_radius
    s1 = r1 * params.theta_max[0]
    s2 = r2 * params.theta_max[1]
    lo = np.array([params.phi_range[0], params.d_range[0], -s1, -s1, -s2, -s2])
    hi = np.array([params.phi_range[1], params.d_range[1], s1, s1, s2, s2])
    return lo, hi


def _spec_actuator_bounds(spec: ArmSpec) -> tuple[Array, Array]:
    """actuator_bounds of any arm: a pull actuator's largest |value| over every segment at its
    theta_max in any plane (coupled tendons add their proximal segments'); direct ones their psi range."""
    lo_q, hi_q = spec.bounds()
    lo = np.full(spec.m, -np.inf)
    hi = np.full(spec.m, np.inf)
    k = len(spec.stem)
    lo[:k], hi[:k] = lo_q[:k], hi_q[:k]
    # a pull of segment t: r sum_j theta_j cos(delta_j + sigma) over the segments it crosses
    ths = np.array([s.theta_max for s in spec.segments])
    row = k
    for t, s in enumerate(spec.segments):
        if s.actuation.type == "direct":
            i = spec.theta_index[t]
            lo[row], hi[row] = lo_q[i], hi_q[i]
            if s.planar is None:
                lo[row + 1], hi[row + 1] = -math.pi, math.pi
        else:
            crossed = ths[: t + 1] if s.actuation.type == "tendons" else ths[t : t + 1]
            bound = s.actuation.pitch_radius * float(crossed.sum())
            lo[row : row + s.actuators], hi[row : row + s.actuators] = -bound, bound
        row += s.actuators
    return lo, hi
