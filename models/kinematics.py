"""Closed-form kinematics of the whole arm (paper eq. 4): frames and the 6x6 tip Jacobian.

Naming: ``T_a_b`` is the 4x4 pose of frame {b} in frame {a} (it maps b-coordinates to a).
Chain: {w} -> Rz(phi) Tz(d) -> {1b} -> seg 1 -> {1e} -> Tz(L_r) -> {2b} -> seg 2 -> {2e}
-> Tz(l_marker) -> {wm} -> Tz(tip_offset) -> tip. psi = [phi, d, theta1, delta1, theta2, delta2].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.constant_curvature import rot_z, segment_jacobian, segment_transform
from models.errors import InputError
from models.robot_params import RobotParams

Array = NDArray[np.float64]


def check_psi(psi: object) -> Array:
    """Return psi as a finite float array of shape (6,); raise InputError otherwise."""
    a = np.asarray(psi, dtype=float)
    if a.shape != (6,):
        raise InputError(f"psi must have 6 entries [phi, d, theta1, delta1, theta2, delta2], got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"psi must be finite, got {a.tolist()}")
    return a


def _tz(z: float) -> Array:
    T = np.eye(4)
    T[2, 3] = z
    return T


@dataclass(frozen=True)
class ArmFrames:
    """Poses in {w} of the arm's frames for one configuration [m]."""

    T_world_1b: Array
    T_world_1e: Array
    T_world_2b: Array
    T_world_2e: Array
    T_world_marker: Array
    T_world_tip: Array

    @property
    def tip(self) -> Array:
        """Tip position in {w} [m]."""
        return self.T_world_tip[:3, 3]


def forward_kinematics(params: RobotParams, psi: object) -> ArmFrames:
    """All frames of the chain in {w} for configuration ``psi``."""
    q = check_psi(psi)
    phi, d, th1, de1, th2, de2 = q
    L1, L2 = params.segment_lengths
    T_w_1b = np.eye(4)
    T_w_1b[:3, :3] = rot_z(phi)
    T_w_1b[2, 3] = d
    T_w_1e = T_w_1b @ segment_transform(L1, th1, de1)
    T_w_2b = T_w_1e @ _tz(params.rigid_length)
    T_w_2e = T_w_2b @ segment_transform(L2, th2, de2)
    T_w_m = T_w_2e @ _tz(params.marker_offset)
    T_w_tip = T_w_m @ _tz(params.tip_offset)
    return ArmFrames(T_w_1b, T_w_1e, T_w_2b, T_w_2e, T_w_m, T_w_tip)


def tip_position(params: RobotParams, psi: object) -> Array:
    """Tip position in {w} [m]."""
    return forward_kinematics(params, psi).tip


def tip_jacobian(params: RobotParams, psi: object, frames: ArmFrames | None = None) -> Array:
    """6x6 Jacobian: rows 0-2 tip linear velocity, rows 3-5 tip-frame angular velocity, in {w}.

    Columns follow psi_dot = [phi_dot, d_dot, theta1_dot, delta1_dot, theta2_dot, delta2_dot].
    """
    q = check_psi(psi)
    fr = frames if frames is not None else forward_kinematics(params, q)
    p_tip = fr.tip
    J = np.zeros((6, 6))
    ez = np.array([0.0, 0.0, 1.0])
    J[:3, 0] = np.cross(ez, p_tip)
    J[3:, 0] = ez
    J[:3, 1] = ez
    L1, L2 = params.segment_lengths
    for col, (T_base, T_end, L, th, de) in (
        (2, (fr.T_world_1b, fr.T_world_1e, L1, q[2], q[3])),
        (4, (fr.T_world_2b, fr.T_world_2e, L2, q[4], q[5])),
    ):
        Jv, Jw = segment_jacobian(L, th, de)
        R = T_base[:3, :3]
        w = R @ Jw
        lever = p_tip - T_end[:3, 3]
        J[:3, col : col + 2] = R @ Jv + np.cross(w.T, lever).T
        J[3:, col : col + 2] = w
    return J
