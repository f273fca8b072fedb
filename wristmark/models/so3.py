"""Rotations on SO(3) for the orientation task: errors, angles, small random rotations.

All rotations are 3x3 matrices mapping a frame's axes into {w} (columns = the frame's axes in
{w}); rotation vectors are axis * angle [rad] expressed in {w}. Built on scipy's Rotation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

Array = NDArray[np.float64]


def rotation_error(R_des: Array, R_meas: Array) -> Array:
    """log(R_des R_meas^T) (3,) [rad] in {w}: the rotation vector that turns the measured frame
    into the desired one (an angular velocity of e / T for T seconds closes the error)."""
    return np.asarray(Rotation.from_matrix(np.asarray(R_des) @ np.asarray(R_meas).T).as_rotvec(), float)


def axis_error(z_des: Array, z_meas: Array) -> Array:
    """Rotation vector (3,) [rad] in {w} of the shortest turn of the unit axis ``z_meas`` onto
    ``z_des`` (perpendicular to both: no component about the axis itself)."""
    a = np.asarray(z_meas, float) / np.linalg.norm(z_meas)
    b = np.asarray(z_des, float) / np.linalg.norm(z_des)
    c = np.cross(a, b)
    s = float(np.linalg.norm(c))
    if s < 1e-12:
        return np.zeros(3)
    return np.asarray(c / s * np.arctan2(s, float(a @ b)), float)


def angle_between(R_a: Array, R_b: Array) -> float:
    """The angle [rad] of the rotation between two frames (0..pi; accurate near 0, unlike the
    arccos of the trace)."""
    return float(Rotation.from_matrix(np.asarray(R_a).T @ np.asarray(R_b)).magnitude())


def axis_angle_between(z_a: Array, z_b: Array) -> float:
    """The angle [rad] between two axis directions (0..pi)."""
    a, b = np.asarray(z_a, float), np.asarray(z_b, float)
    c = float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def perturb(R: Array, rng: np.random.Generator, rms: float) -> Array:
    """``R`` turned by a random rotation Exp(n) in {w}, n isotropic Gaussian with per-axis sigma
    rms / sqrt(3): the angle turned is |n|, of RMS ``rms`` [rad]."""
    n = rng.normal(0.0, rms / np.sqrt(3.0), 3)
    return np.asarray(Rotation.from_rotvec(n).as_matrix() @ np.asarray(R, float), float)


def rotvec(R: Array) -> Array:
    """The rotation vector (3,) [rad] of a rotation matrix."""
    return np.asarray(Rotation.from_matrix(np.asarray(R, float)).as_rotvec(), float)
