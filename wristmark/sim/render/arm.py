"""Ray casting of the distal arm (tube, rigid link, marker sleeve, gripper) in one camera.

Rays leave the camera centre through raw (distorted) pixel positions: a per-camera map of
normalized image coordinates, computed once with the camera's exact inverse distortion, is
interpolated at the supersample positions, so the checker corners appear where
``Camera.project`` puts them. Primitives live in the camera frame [m]: capsules (tube pieces,
link, gripper) and the marker sleeve (a finite cylinder over the marker's z extent with the
exact pattern of :meth:`MarkerModel.is_black`: checker rows and any coded marker's patches).
Shading: coaxial light (light at the camera), Lambert plus a specular lobe, inverse-square
falloff. The per-ray work runs in the numba kernels of
:mod:`sim.render.culling` and :mod:`sim.render.raycast`; this module builds the primitives,
the ray map and the tile plan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.culling import NEAR, cull_tiles
from wristmark.sim.render.raycast import CAPSULE_COLS, SLEEVE_COLS, TILE, ray_directions, raycast_tiles

Array = NDArray[np.float64]
Box = tuple[int, int, int, int]  # pixel rectangle (u0, v0, u1, v1), u1 and v1 exclusive


@dataclass(frozen=True)
class Material:
    """Surface reflectance: albedo (B, G, R) in [0, 1], specular strength and exponent."""

    albedo: tuple[float, float, float]
    specular: float
    shininess: float


TUBE = Material((0.22, 0.2, 0.18), 0.35, 18.0)
METAL = Material((0.55, 0.55, 0.56), 0.9, 60.0)
MARKER_WHITE = Material((0.86, 0.86, 0.84), 0.08, 25.0)
MARKER_BLACK = Material((0.05, 0.05, 0.05), 0.08, 25.0)
MATERIALS = (TUBE, METAL, MARKER_BLACK, MARKER_WHITE)  # ids used by the kernels
_MATS = np.array([[*m.albedo, m.specular, m.shininess] for m in MATERIALS], np.float64)


def glossy_materials(f0: float, alpha: float, lights: Array) -> Array:
    """The kernels' material rows with the sleeve's glossy laminate: the matte rows, then
    (F0, GGX alpha) and one row per light output (x, y, z [m] in the camera frame, weight:
    its share of the coaxial light's irradiance); see :mod:`sim.render.raycast`."""
    L = np.asarray(lights, float).reshape(-1, 4)
    rows = np.zeros((1 + len(L), _MATS.shape[1]))
    rows[0, :2] = f0, alpha
    rows[1:, :4] = L
    return np.ascontiguousarray(np.vstack([_MATS, rows]))


@dataclass(frozen=True)
class Capsule:
    """A capsule (cylinder with spherical ends) from a to b [m, camera frame] of radius r [m]."""

    a: Array
    b: Array
    r: float
    material: Material
    caps: tuple[bool, bool] = (True, True)  # draw the spherical ends at a, b


@dataclass(frozen=True)
class Sleeve:
    """The marker sleeve: pose of {wm} in the camera frame (4x4) and the marker geometry."""

    T_cam_marker: Array
    marker: MarkerModel


class RayMap:
    """Normalized image coordinates (x/z, y/z) of every raw pixel of one camera, padded to whole
    tiles plus a 1 px border, per-tile bounds (box, centre, radius) used for culling, and the
    unit rays through the pixel centres, per tile (``dirs``: what one sample per pixel traces)."""

    def __init__(self, camera: Camera, image_size: tuple[int, int]) -> None:
        w, h = image_size
        ty, tx = -(-h // TILE), -(-w // TILE)
        u, v = np.meshgrid(np.arange(-1.0, tx * TILE + 1.0), np.arange(-1.0, ty * TILE + 1.0))
        xy = camera.undistort(np.column_stack([u.ravel(), v.ravel()]))
        self.size = (w, h)
        self.tiles = (ty, tx)
        self.xy = np.ascontiguousarray(xy.reshape(ty * TILE + 2, tx * TILE + 2, 2), np.float64)
        blk = self.xy[1:-1, 1:-1].reshape(ty, TILE, tx, TILE, 2).transpose(0, 2, 1, 3, 4).reshape(ty, tx, -1, 2)
        self.tile_lo = np.ascontiguousarray(blk.min(axis=2))
        self.tile_hi = np.ascontiguousarray(blk.max(axis=2))
        self.tile_c = 0.5 * (self.tile_lo + self.tile_hi)
        self.tile_r = np.ascontiguousarray(np.linalg.norm(blk - self.tile_c[:, :, None, :], axis=3).max(axis=2))
        self.dirs = ray_directions(self.xy, ty, tx)  # (ty, tx, 3, TILE^2) unit rays through the pixel centres

    def tiles_box(self, lo: Array, hi: Array) -> Box | None:
        """Pixel rectangle (u0, v0, u1, v1) of the tiles whose rays overlap the normalized box."""
        hit = np.all((self.tile_hi >= lo) & (self.tile_lo <= hi), axis=2)
        if not hit.any():
            return None
        js, is_ = np.nonzero(hit)
        return (int(is_.min()) * TILE, int(js.min()) * TILE, (int(is_.max()) + 1) * TILE, (int(js.max()) + 1) * TILE)


def pack_capsules(capsules: list[Capsule]) -> Array:
    """Capsules as the kernels' float64 rows (n, CAPSULE_COLS); see :mod:`sim.render.raycast`."""
    out = np.zeros((len(capsules), CAPSULE_COLS))
    for i, c in enumerate(capsules):
        a, b = np.asarray(c.a, float), np.asarray(c.b, float)
        ba = b - a
        out[i, :6] = *a, *b
        out[i, 6:10] = c.r, float(c.caps[0]), float(c.caps[1]), MATERIALS.index(c.material)
        out[i, 10:] = *ba, ba @ ba, -(ba @ a), a @ a
    return out


def pack_sleeve(s: Sleeve) -> Array:
    """The sleeve as the kernels' float64 row (SLEEVE_COLS,): R, camera centre in {wm}, sizes,
    z extent."""
    R, p = s.T_cam_marker[:3, :3], s.T_cam_marker[:3, 3]
    m = s.marker
    row = [*R.ravel(), *(-(R.T @ p)), m.radius, m.row_height, m.columns, m.beta, *m.z_extent]
    return np.array(row, np.float64).reshape(SLEEVE_COLS)


def _sleeve_bounds(s: Sleeve) -> tuple[Array, Array] | None:
    ang = np.linspace(0, 2 * np.pi, 33)
    z_lo, z_hi = s.marker.z_extent
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)]) * s.marker.radius
    pts = np.vstack([ring + [0, 0, z_hi], ring + [0, 0, z_lo]]) @ s.T_cam_marker[:3, :3].T + s.T_cam_marker[:3, 3]
    if np.any(pts[:, 2] < NEAR):
        return None
    P = pts[:, :2] / pts[:, 2:3]
    m = 0.02 * s.marker.radius / pts[:, 2].min()
    return P.min(axis=0) - m, P.max(axis=0) + m


def sleeve_box(ray_map: RayMap, sleeve: Sleeve) -> Box | None:
    """Tile-aligned pixel box (u0, v0, u1, v1) that holds the marker sleeve, or None if unseen."""
    bnd = _sleeve_bounds(sleeve)
    return None if bnd is None else ray_map.tiles_box(*bnd)


@dataclass(frozen=True)
class ArmPlan:
    """What one camera ray-casts: tiles (tile row, tile column, supersampling), each tile's
    primitives ``prim[ptr[t]:ptr[t + 1]]`` (capsule rows, then n_caps = the sleeve), the packed
    primitives, the sleeve's patches (n, 4) and ``box``, the pixel rectangle (u0, v0, u1, v1) of
    the tiles within the image."""

    tiles: NDArray[np.int64]
    ptr: NDArray[np.int64]
    prim: NDArray[np.int64]
    caps: Array
    sleeve: Array
    patches: Array
    box: Box


def plan_arm(ray_map: RayMap, capsules: list[Capsule], sleeve: Sleeve, ss: int, arm_ss: int) -> ArmPlan | None:
    """Cull the primitives (camera frame) per tile; tiles of the sleeve's box get ``ss`` samples
    per pixel axis, the rest of the arm ``arm_ss``. None if nothing is in view."""
    caps = pack_capsules(capsules)
    sb = _sleeve_bounds(sleeve)
    lo, hi = (np.zeros(2), np.zeros(2)) if sb is None else sb
    mask = cull_tiles(ray_map.tile_c, ray_map.tile_r, ray_map.tile_lo, ray_map.tile_hi, caps, lo, hi, sb is not None)
    used = mask.any(axis=2)
    if not used.any():
        return None
    js, is_ = np.nonzero(used)
    tss = np.full(len(js), arm_ss, np.int64)
    mbox = ray_map.tiles_box(*sb) if (sb is not None and ss != arm_ss) else None
    if mbox is not None:  # the marker and what surrounds it at full supersampling
        inside = (is_ >= mbox[0] // TILE) & (is_ < mbox[2] // TILE) & (js >= mbox[1] // TILE) & (js < mbox[3] // TILE)
        tss[inside] = ss
    elif ss == arm_ss:
        tss[:] = ss
    sub = mask[js, is_]
    ptr = np.concatenate([[0], np.cumsum(sub.sum(axis=1))]).astype(np.int64)
    prim = np.nonzero(sub)[1].astype(np.int64)
    w, h = ray_map.size
    u1, v1 = min(w, (int(is_.max()) + 1) * TILE), min(h, (int(js.max()) + 1) * TILE)
    box = (int(is_.min()) * TILE, int(js.min()) * TILE, u1, v1)
    tiles = np.column_stack([js, is_, tss]).astype(np.int64)
    return ArmPlan(tiles, ptr, prim, caps, pack_sleeve(sleeve), sleeve.marker.patch_array(), box)


def render_arm(
    ray_map: RayMap,
    plan: ArmPlan,
    gain: float,
    out: NDArray[np.float32],
    origin: tuple[int, int],
    flat: bool = False,
    adaptive: bool = True,
    mats: Array | None = None,
) -> int:
    """Ray-cast ``plan`` and blend the arm over the background radiance already in ``out``
    (float32 BGR [grey levels]; ``out[0, 0]`` is pixel ``origin`` = (u, v)). Each pixel becomes
    the mean of its samples (background where a sample misses). ``gain``: grey levels for unit
    radiance; ``flat``: albedo only, no lighting; ``adaptive``: supersample only pixels whose
    neighbourhood changes surface (see :func:`sim.render.raycast.raycast_tiles`); ``mats``: the
    kernels' material rows (default: the matte :data:`MATERIALS`; :func:`glossy_materials` adds
    the sleeve's laminate and the light outputs). Returns the number of rays cast."""
    if out.dtype != np.float32 or out.ndim != 3 or out.shape[2] != 3:
        raise InputError(f"out must be a float32 (h, w, 3) image, got {out.dtype} {out.shape}")
    return int(
        raycast_tiles(
            ray_map.xy, ray_map.dirs, plan.tiles, plan.ptr, plan.prim, plan.caps, plan.sleeve, plan.patches,
            _MATS if mats is None else mats, float(gain), bool(flat), bool(adaptive), out, int(origin[0]),
            int(origin[1]),
        )
    )
