"""One constant-curvature segment (paper eq. 1-2), exact and division-free near theta = 0.

Frames: base ring {tb} -> end ring {te}. The segment bends by theta >= 0 in the plane at angle
delta: p = L [cos(delta) f(theta), -sin(delta) f(theta), g(theta)], with f = (1 - cos)/theta,
g = sin/theta, and R = Rz(-delta) Ry(theta) Rz(delta). Below |theta| < 0.2, f, g and their
derivatives come from Taylor series truncated far below double precision; above it from
cancellation-free forms (1 - cos t = 2 sin^2(t/2)).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Rot = tuple[float, float, float, float, float, float, float, float, float]
Vec = tuple[float, float, float]

_SERIES_BELOW = 0.2  # [rad]; series truncation below it < 1e-18 relative


def f_g(theta: float) -> tuple[float, float, float, float]:
    """Return f = (1-cos t)/t, g = sin t / t and their derivatives f', g' (smooth at t = 0).

    Cancellation-free: f = 2 sin^2(t/2)/t, f' = (sin t - f)/t, g' = (cos t - g)/t, and below
    |t| < 0.2 Taylor series to t^11 (the direct g' loses ~3 eps/t^2 relative, so the
    series takes over well before that matters).
    """
    t = theta
    if abs(t) < _SERIES_BELOW:
        u = t * t
        # fmt: off
        f = t * (1 / 2 + u * (-1 / 24 + u * (1 / 720 + u * (-1 / 40320 + u * (
            1 / 3628800 - u / 479001600)))))
        g = 1 + u * (-1 / 6 + u * (1 / 120 + u * (-1 / 5040 + u * (1 / 362880 - u / 39916800))))
        df = 1 / 2 + u * (-1 / 8 + u * (1 / 144 + u * (-1 / 5760 + u * (
            1 / 403200 - u / 43545600))))
        dg = t * (-1 / 3 + u * (1 / 30 + u * (-1 / 840 + u * (1 / 45360 + u * (
            -1 / 3991680 + u / 518918400)))))
        # fmt: on
        return f, g, df, dg
    sh = math.sin(0.5 * t)
    f = 2.0 * sh * sh / t
    g = math.sin(t) / t
    return f, g, (math.sin(t) - f) / t, (math.cos(t) - g) / t


def rot_z(a: float) -> NDArray[np.float64]:
    """Rotation about z by ``a`` [rad]."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(a: float) -> NDArray[np.float64]:
    """Rotation about y by ``a`` [rad]."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def segment_pose(length: float, theta: float, delta: float) -> tuple[Rot, Vec]:
    """Pose of {te} in {tb} as plain floats: (R row-major 9-tuple, p 3-tuple [m]).

    R = Rz(-delta) Ry(theta) Rz(delta) expanded; p = L [cos(delta) f, -sin(delta) f, g].
    The scalar core of :func:`segment_transform`, used on hot paths (no numpy calls).
    """
    f, g, _, _ = f_g(theta)
    c, s = math.cos(delta), math.sin(delta)
    C, S = math.cos(theta), math.sin(theta)
    v = theta * f  # = 1 - cos(theta), without cancellation near 0
    cs_v = c * s * v
    R = (1.0 - c * c * v, cs_v, c * S, cs_v, 1.0 - s * s * v, -s * S, -S * c, S * s, C)
    return R, (length * c * f, -length * s * f, length * g)


def segment_transform(length: float, theta: float, delta: float) -> NDArray[np.float64]:
    """4x4 pose of {te} in {tb} for a segment of ``length`` [m], bend ``theta``, plane ``delta``."""
    R, p = segment_pose(length, theta, delta)
    return np.array(
        (R[0], R[1], R[2], p[0], R[3], R[4], R[5], p[1], R[6], R[7], R[8], p[2], 0.0, 0.0, 0.0, 1.0)
    ).reshape(4, 4)


def segment_point(length: float, theta: float, delta: float, s: float) -> NDArray[np.float64]:
    """Centreline point at arc fraction ``s`` in [0, 1] of the segment, in {tb} [m]."""
    return segment_transform(s * length, s * theta, delta)[:3, 3]


def segment_jacobian(
    length: float, theta: float, delta: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Local Jacobians in {tb}: (Jv 3x2, Jw 3x2) w.r.t. [theta, delta] of {te}'s origin and frame.

    Jw columns: d/dtheta -> Rz(-delta) e_y = [sin d, cos d, 0]; d/ddelta -> R e_z - e_z.
    """
    f, g, df, dg = f_g(theta)
    cd, sd = math.cos(delta), math.sin(delta)
    S = math.sin(theta)
    L = length
    Jv = np.array((L * cd * df, -L * sd * f, -L * sd * df, -L * cd * f, L * dg, 0.0)).reshape(3, 2)
    Jw = np.array((sd, cd * S, cd, -sd * S, 0.0, -theta * f)).reshape(3, 2)
    return Jv, Jw
