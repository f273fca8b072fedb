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


def chord_starts(P_model: Array, P_obs: Array, n: int = 12) -> list[Array]:
    """4x4 rigid transforms that put two model points (2, 3) on two observed ones (2, 3) along
    their chord (least squares: the chords' midpoints coincide), turned about it by k 2 pi / n, k
    = 0..n-1: a start pose from two stereo pairs, whose turn about the chord they leave open."""
    a, b = P_model[1] - P_model[0], P_obs[1] - P_obs[0]
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    R0 = np.eye(3) + K + K @ K / (1.0 + c) if c > -1.0 + 1e-9 else (
        2.0 * np.outer(p := np.linalg.svd(a[None, :])[2][1], p) - np.eye(3))  # a half turn about a normal of a
    Kb = np.array([[0, -b[2], b[1]], [b[2], 0, -b[0]], [-b[1], b[0], 0]])
    out = []
    for k in range(n):
        phi = 2.0 * np.pi * k / n
        R = (np.eye(3) + np.sin(phi) * Kb + (1.0 - np.cos(phi)) * Kb @ Kb) @ R0
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, P_obs.mean(axis=0) - R @ P_model.mean(axis=0)
        out.append(T)
    return out
