"""Closed-form kinematics of the whole arm (paper eq. 4): frames and the 6x6 tip Jacobian.

Naming: ``T_a_b`` is the 4x4 pose of frame {b} in frame {a} (it maps b-coordinates to a).
Chain: {w} -> Rz(phi) Tz(d) -> {1b} -> seg 1 -> {1e} -> Tz(L_r) -> {2b} -> seg 2 -> {2e}
-> Tz(l_marker) -> {wm} -> Tz(tip_offset) -> tip. psi = [phi, d, theta1, delta1, theta2, delta2].
This is the one implementation of the chain: the simulated true arm (sim/plant.py) and the
viewer (viz/scene.py) call it too, passing ``stem_bend`` where the exposed stem bends.

Speed: the chain is evaluated on plain Python floats (rotations as row-major 9-tuples) and
copied into numpy once per call; numpy calls on 3x3/4x4 arrays cost more than the arithmetic.
FK + 6x6 Jacobian ~30 us here, against ~540 us with per-matrix numpy (bench/kinematics.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.constant_curvature import Rot, Vec, f_g, segment_pose
from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams

Array = NDArray[np.float64]


def check_psi(psi: object) -> Array:
    """Return psi as a finite float array of shape (6,); raise InputError otherwise."""
    a = np.asarray(psi, dtype=float)
    if a.shape != (6,):
        raise InputError(
            f"psi must have 6 entries [phi, d, theta1, delta1, theta2, delta2], got shape {a.shape}"
        )
    if not all(map(math.isfinite, a.tolist())):
        raise InputError(f"psi must be finite, got {a.tolist()}")
    return a


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


def _compose(Ra: Rot, pa: Vec, Rb: Rot, pb: Vec) -> tuple[Rot, Vec]:
    """(Ra, pa) * (Rb, pb) on plain floats: rotation row-major 9-tuple, translation 3-tuple."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = Ra
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = Rb
    x, y, z = pb
    # fmt: off
    R = (
        a0 * b0 + a1 * b3 + a2 * b6, a0 * b1 + a1 * b4 + a2 * b7, a0 * b2 + a1 * b5 + a2 * b8,
        a3 * b0 + a4 * b3 + a5 * b6, a3 * b1 + a4 * b4 + a5 * b7, a3 * b2 + a4 * b5 + a5 * b8,
        a6 * b0 + a7 * b3 + a8 * b6, a6 * b1 + a7 * b4 + a8 * b7, a6 * b2 + a7 * b5 + a8 * b8,
    )
    # fmt: on
    p = (
        a0 * x + a1 * y + a2 * z + pa[0],
        a3 * x + a4 * y + a5 * z + pa[1],
        a6 * x + a7 * y + a8 * z + pa[2],
    )
    return R, p


def _along_z(R: Rot, p: Vec, dz: float) -> Vec:
    """Origin of (R, p) * Tz(dz)."""
    return (p[0] + R[2] * dz, p[1] + R[5] * dz, p[2] + R[8] * dz)


def _homogeneous_stack(poses: list[tuple[Rot, Vec]]) -> Array:
    """(n, 4, 4) array of the poses, filled in one numpy call."""
    flat: list[float] = []
    for R, p in poses:
        flat += (R[0], R[1], R[2], p[0], R[3], R[4], R[5], p[1], R[6], R[7], R[8], p[2])
        flat += _LAST_ROW
    return np.fromiter(flat, np.float64, len(flat)).reshape(len(poses), 4, 4)


_LAST_ROW = (0.0, 0.0, 0.0, 1.0)


def _chain(params: RobotParams, q: list[float], stem_bend: float = 0.0) -> list[tuple[Rot, Vec]]:
    """Poses in {w} of {1b}, {1e}, {2b}, {2e}, {wm}, tip as plain floats (see _compose)."""
    phi, d, th1, de1, th2, de2 = q
    L1, L2 = params.segment_lengths
    c, s = math.cos(phi), math.sin(phi)
    R1b: Rot = (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    p1b: Vec = (0.0, 0.0, d)
    if stem_bend != 0.0:  # the exposed stem: an arc of length d bent in segment 1's plane
        R1b, p1b = _compose(R1b, (0.0, 0.0, 0.0), *segment_pose(d, stem_bend, de1))
    R1e, p1e = _compose(R1b, p1b, *segment_pose(L1, th1, de1))
    p2b = _along_z(R1e, p1e, params.rigid_length)
    R2e, p2e = _compose(R1e, p2b, *segment_pose(L2, th2, de2))
    pm = _along_z(R2e, p2e, params.marker_offset)
    ptip = _along_z(R2e, pm, params.tip_offset)
    return [(R1b, p1b), (R1e, p1e), (R1e, p2b), (R2e, p2e), (R2e, pm), (R2e, ptip)]


def forward_kinematics(params: RobotParams, psi: object, stem_bend: float = 0.0) -> ArmFrames:
    """All frames of the chain in {w} [m] for configuration ``psi`` [rad, m, rad, rad, rad, rad].
    ``stem_bend`` [rad]: the exposed stem (incision to {1b}, length d) bent as a constant-curvature
    arc in segment 1's plane (delta1), as the simulated true arm's stem coupling does; 0 (the model): straight."""
    T = _homogeneous_stack(_chain(params, check_psi(psi).tolist(), float(stem_bend)))
    return ArmFrames(T[0], T[1], T[2], T[3], T[4], T[5])


def tip_position(params: RobotParams, psi: object) -> Array:
    """Tip position in {w} [m]."""
    return np.array(_chain(params, check_psi(psi).tolist())[5][1])


def _segment_columns(
    length: float, theta: float, delta: float, Rb: Rot, p_end: Vec, p_tip: Vec
) -> tuple[list[float], list[float]]:
    """Tip Jacobian columns [theta, delta] of one segment: 6 linear and 6 angular entries,
    row-major (3x2 each), in {w}. ``Rb`` is the segment base's rotation in {w}."""
    f, g, df, dg = f_g(theta)
    cd, sd = math.cos(delta), math.sin(delta)
    S = math.sin(theta)
    # local (base-frame) columns: Jv = L [cd df, -sd f; -sd df, -cd f; dg, 0],
    # Jw = [sd, cd S; cd, -sd S; 0, -theta f]
    r0, r1, r2, r3, r4, r5, r6, r7, r8 = Rb
    lx, ly, lz = p_tip[0] - p_end[0], p_tip[1] - p_end[1], p_tip[2] - p_end[2]
    # angular columns in {w}: R wt, R wd
    atx, aty, atz = r0 * sd + r1 * cd, r3 * sd + r4 * cd, r6 * sd + r7 * cd
    wdx, wdy, wdz = cd * S, -sd * S, -theta * f
    adx = r0 * wdx + r1 * wdy + r2 * wdz
    ady = r3 * wdx + r4 * wdy + r5 * wdz
    adz = r6 * wdx + r7 * wdy + r8 * wdz
    # linear columns: R v + w x lever
    vtx, vty, vtz = length * cd * df, -length * sd * df, length * dg
    vdx, vdy = -length * sd * f, -length * cd * f
    lin = [
        r0 * vtx + r1 * vty + r2 * vtz + aty * lz - atz * ly,
        r0 * vdx + r1 * vdy + ady * lz - adz * ly,
        r3 * vtx + r4 * vty + r5 * vtz + atz * lx - atx * lz,
        r3 * vdx + r4 * vdy + adz * lx - adx * lz,
        r6 * vtx + r7 * vty + r8 * vtz + atx * ly - aty * lx,
        r6 * vdx + r7 * vdy + adx * ly - ady * lx,
    ]
    return lin, [atx, adx, aty, ady, atz, adz]


def _pose_of(T: Array) -> tuple[Rot, Vec]:
    """(R, p) of a 4x4 pose as plain floats."""
    r = T.ravel().tolist()
    return (r[0], r[1], r[2], r[4], r[5], r[6], r[8], r[9], r[10]), (r[3], r[7], r[11])


def tip_jacobian(params: RobotParams, psi: object, frames: ArmFrames | None = None) -> Array:
    """6x6 Jacobian: rows 0-2 tip linear velocity, rows 3-5 tip-frame angular velocity, in {w}.

    Columns follow psi_dot = [phi_dot, d_dot, theta1_dot, delta1_dot, theta2_dot, delta2_dot].
    ``frames`` (from :func:`forward_kinematics` at the same psi) saves recomputing the chain.
    """
    q = check_psi(psi).tolist()
    if frames is None:
        chain = _chain(params, q)
        R1b, R2b = chain[0][0], chain[2][0]
        p1e, p2e, ptip = chain[1][1], chain[3][1], chain[5][1]
    else:
        R1b, R2b = _pose_of(frames.T_world_1b)[0], _pose_of(frames.T_world_2b)[0]
        p1e, p2e = _pose_of(frames.T_world_1e)[1], _pose_of(frames.T_world_2e)[1]
        ptip = _pose_of(frames.T_world_tip)[1]
    L1, L2 = params.segment_lengths
    v1, w1 = _segment_columns(L1, q[2], q[3], R1b, p1e, ptip)
    v2, w2 = _segment_columns(L2, q[4], q[5], R2b, p2e, ptip)
    # fmt: off
    return np.fromiter((
        -ptip[1], 0.0, v1[0], v1[1], v2[0], v2[1],
        ptip[0], 0.0, v1[2], v1[3], v2[2], v2[3],
        0.0, 1.0, v1[4], v1[5], v2[4], v2[5],
        0.0, 0.0, w1[0], w1[1], w2[0], w2[1],
        0.0, 0.0, w1[2], w1[3], w2[2], w2[3],
        1.0, 0.0, w1[4], w1[5], w2[4], w2[5],
    ), np.float64, 36).reshape(6, 6)
    # fmt: on
