"""The chain's arithmetic on plain Python floats, shared by models.kinematics (the reference arm)
and models.arm_kinematics (any arm): rotations as row-major 9-tuples, translations as 3-tuples
(numpy calls on 3x3/4x4 arrays cost more than the arithmetic)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.constant_curvature import Rot, Vec, f_g

Array = NDArray[np.float64]


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
