"""Rigid transforms for the tracker's start poses: a roll about z and the Kabsch fit."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def roll_about_z(a: float) -> Array:
    """4x4 rotation by a [rad] about z."""
    c, sn = np.cos(a), np.sin(a)
    return np.array([[c, -sn, 0, 0], [sn, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def kabsch(P_model: Array, P_obs: Array) -> Array:
    """4x4 rigid transform T with P_obs ~ R P_model + t (least squares, proper rotation)."""
    cm, co = P_model.mean(axis=0), P_obs.mean(axis=0)
    H = (P_model - cm).T @ (P_obs - co)
    u, _, vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T)) or 1.0])
    R = vt.T @ D @ u.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, co - R @ cm
    return T
