"""Numba kernel of per-tile culling of the arms' primitives (which tiles each may cover).

Tiles are squares of raw pixels described in normalized image coordinates (x/z, y/z): a disc
(centre, radius) and a box holding the rays of their pixels. Capsules are the packed rows of
:mod:`sim.render.raycast` (of all the arms drawn); each arm's sleeve comes as a normalized-plane
box. The kernel uses only
names of this file (numba's on-disk cache does not notice changes in other files).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

NEAR = 0.01  # near clipping distance along the optical axis [m]

F64 = NDArray[np.float64]
jit = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")


@jit
def _capsule_margin(c: F64) -> tuple[bool, float, float, float, float, float]:
    """Normalized-plane segment (x0, y0, x1, y1) and margin covering capsule row c, or not seen."""
    ax, ay, az, bx, by, bz, r = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    if az < NEAR and bz < NEAR:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0
    if az < NEAR or bz < NEAR:  # clip at the near plane
        s = (NEAR - az) / (bz - az)
        px, py, pz = ax + s * (bx - ax), ay + s * (by - ay), az + s * (bz - az)
        if az < NEAR:
            ax, ay, az = px, py, pz
        else:
            bx, by, bz = px, py, pz
    x0, y0, x1, y1 = ax / az, ay / az, bx / bz, by / bz
    zmin = min(az, bz)
    widen = 1.2 + max(x0 * x0 + y0 * y0, x1 * x1 + y1 * y1)  # off-axis spheres project elongated
    m = widen * r / (zmin - r) if zmin > r * 1.5 else 10.0
    return True, x0, y0, x1, y1, m


@jit
def cull_tiles(
    tile_c: F64, tile_r: F64, tile_lo: F64, tile_hi: F64, caps: F64, sleeve_lo: F64, sleeve_hi: F64,
    sleeve_seen: NDArray[np.bool_],
) -> NDArray[np.bool_]:
    """(ty, tx, n_caps + k) mask of the primitives (capsules, then the k sleeves) whose image
    may overlap each tile: capsules by distance of the tile's ray disc (centre ``tile_c``,
    radius ``tile_r`` in normalized coordinates) to their projected segment, sleeve j (if
    ``sleeve_seen[j]``) by overlap of its normalized-plane box [sleeve_lo[j], sleeve_hi[j]]
    (rows of (k, 2) arrays) with the tile's [tile_lo, tile_hi]."""
    ty, tx = tile_r.shape
    nc = caps.shape[0]
    ns = sleeve_seen.shape[0]
    mask = np.zeros((ty, tx, nc + ns), np.bool_)
    for p in range(nc):
        seen, x0, y0, x1, y1, m = _capsule_margin(caps[p])
        if not seen:
            continue
        ex, ey = x1 - x0, y1 - y0
        L2 = ex * ex + ey * ey
        for j in range(ty):
            for i in range(tx):
                cx, cy = tile_c[j, i, 0], tile_c[j, i, 1]
                k = 0.0
                if L2 > 0.0:
                    k = min(max(((cx - x0) * ex + (cy - y0) * ey) / L2, 0.0), 1.0)
                gx, gy = cx - (x0 + k * ex), cy - (y0 + k * ey)
                mask[j, i, p] = math.sqrt(gx * gx + gy * gy) <= tile_r[j, i] + m
    for s in range(ns):
        if not sleeve_seen[s]:
            continue
        for j in range(ty):
            for i in range(tx):
                mask[j, i, nc + s] = (
                    tile_hi[j, i, 0] >= sleeve_lo[s, 0]
                    and tile_hi[j, i, 1] >= sleeve_lo[s, 1]
                    and tile_lo[j, i, 0] <= sleeve_hi[s, 0]
                    and tile_lo[j, i, 1] <= sleeve_hi[s, 1]
                )
    return mask
