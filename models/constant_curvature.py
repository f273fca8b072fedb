"""One constant-curvature segment (paper eq. 1-2), exact and division-free near theta = 0.

Frames: base ring {tb} -> end ring {te}. The segment bends by theta >= 0 in the plane at angle
delta: p = L [cos(delta) f(theta), -sin(delta) f(theta), g(theta)], with f = (1 - cos)/theta,
g = sin/theta, and R = Rz(-delta) Ry(theta) Rz(delta). Below |theta| < 1e-3, f, g and their
derivatives come from Taylor series truncated far below double precision.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

_SERIES_BELOW = 1e-3  # [rad]; truncation error of the series there is < 1e-22


def f_g(theta: float) -> tuple[float, float, float, float]:
    """Return f = (1-cos t)/t, g = sin t / t and their derivatives f', g' (smooth at t = 0)."""
    t = theta
    if abs(t) < _SERIES_BELOW:
        t2 = t * t
        f = t * (0.5 - t2 / 24.0 + t2 * t2 / 720.0)
        g = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        df = 0.5 - t2 / 8.0 + t2 * t2 / 144.0
        dg = t * (-1.0 / 3.0 + t2 / 30.0 - t2 * t2 / 840.0)
        return f, g, df, dg
    s, c = math.sin(t), math.cos(t)
    f = (1.0 - c) / t
    g = s / t
    df = (t * s - (1.0 - c)) / (t * t)
    dg = (t * c - s) / (t * t)
    return f, g, df, dg


def rot_z(a: float) -> NDArray[np.float64]:
    """Rotation about z by ``a`` [rad]."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(a: float) -> NDArray[np.float64]:
    """Rotation about y by ``a`` [rad]."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def segment_transform(length: float, theta: float, delta: float) -> NDArray[np.float64]:
    """4x4 pose of {te} in {tb} for a segment of ``length`` [m], bend ``theta``, plane ``delta``."""
    f, g, _, _ = f_g(theta)
    T = np.eye(4)
    T[:3, :3] = rot_z(-delta) @ rot_y(theta) @ rot_z(delta)
    T[:3, 3] = length * np.array([math.cos(delta) * f, -math.sin(delta) * f, g])
    return T


def segment_point(length: float, theta: float, delta: float, s: float) -> NDArray[np.float64]:
    """Centreline point at arc fraction ``s`` in [0, 1] of the segment, in {tb} [m]."""
    return segment_transform(s * length, s * theta, delta)[:3, 3]


def segment_jacobian(
    length: float, theta: float, delta: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Local Jacobians in {tb}: (Jv 3x2, Jw 3x2) w.r.t. [theta, delta] of {te}'s origin and frame."""
    f, g, df, dg = f_g(theta)
    cd, sd = math.cos(delta), math.sin(delta)
    Jv = length * np.array([[cd * df, -sd * f], [-sd * df, -cd * f], [dg, 0.0]])
    R = rot_z(-delta) @ rot_y(theta) @ rot_z(delta)
    w_theta = np.array([sd, cd, 0.0])  # Rz(-delta) e_y
    w_delta = R[:, 2] - np.array([0.0, 0.0, 1.0])
    return Jv, np.column_stack([w_theta, w_delta])
