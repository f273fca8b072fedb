"""Ray casting of the distal arms (tube, rigid link, marker sleeve, gripper) in one camera.

One arm or several at once (each with its own marker sleeve): the capsules of all arms and
their k sleeves go into one plan, and every ray keeps its nearest hit among all of them, so
the arms hide one another where they cross.

Rays leave the camera centre through raw (distorted) pixel positions: a per-camera map of
normalized image coordinates, computed once with the camera's exact inverse distortion, is
interpolated at the supersample positions, so the checker corners appear where
``Camera.project`` puts them. Primitives live in the camera frame [m]: capsules (tube pieces,
link, gripper) and the marker sleeve (a finite cylinder over the marker's z extent with the
exact pattern of :meth:`MarkerModel.is_black`: checker rows and any coded marker's patches),
one per arm.
Shading: coaxial light (light at the camera), Lambert plus a specular lobe, inverse-square
falloff. The per-ray work runs in the numba kernels of
:mod:`sim.render.culling` and :mod:`sim.render.raycast`; this module builds the primitives,
the ray map and the tile plan.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.culling import NEAR, cull_tiles
from wristmark.sim.render.pixel_grid import undistorted_grid
from wristmark.sim.render.raycast import CAPSULE_COLS, SLEEVE_COLS, TILE, ray_directions, raycast_tiles, trace

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
        self.size = (w, h)
        self.tiles = (ty, tx)
        self.xy = undistorted_grid(camera, -1.0, -1.0, tx * TILE + 2, ty * TILE + 2)  # camera.undistort's numbers
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


RAY_MAP_CACHE = 4  # ray maps kept per process (~85 MB each at 1080p): two stereo pairs


def ray_map(camera: Camera, image_size: tuple[int, int]) -> RayMap:
    """The :class:`RayMap` of ``camera`` at ``image_size`` (w, h) [px], built once per process
    and shared: building one undistorts every pixel (seconds at 1080p), and renderers of the same
    camera (every run of a sweep, every experiment of a session) need the same map. Its arrays
    are read only by the renderer's kernels; do not write to them."""
    K, dist = np.ascontiguousarray(camera.K, np.float64), np.ascontiguousarray(camera.dist, np.float64)
    return _cached_ray_map(K.tobytes(), dist.tobytes(), (int(image_size[0]), int(image_size[1])))


@functools.lru_cache(maxsize=RAY_MAP_CACHE)
def _cached_ray_map(K: bytes, dist: bytes, image_size: tuple[int, int]) -> RayMap:
    return RayMap(Camera(np.frombuffer(K).reshape(3, 3), np.frombuffer(dist)), image_size)


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


def pack_sleeve(s: Sleeve, patch_offset: int = 0) -> Array:
    """The sleeve as the kernels' float64 row (SLEEVE_COLS,): R, camera centre in {wm}, sizes,
    z extent, then its patches' rows [patch_offset, patch_offset + n_patches) in the kernels'
    patch array (see :func:`pack_sleeves`)."""
    R, p = s.T_cam_marker[:3, :3], s.T_cam_marker[:3, 3]
    m = s.marker
    row = [*R.ravel(), *(-(R.T @ p)), m.radius, m.row_height, m.columns, m.beta, *m.z_extent,
           patch_offset, patch_offset + len(m.patches)]
    return np.array(row, np.float64).reshape(SLEEVE_COLS)


def pack_sleeves(sleeves: Sequence[Sleeve]) -> tuple[Array, Array]:
    """The sleeves as the kernels' rows (k, SLEEVE_COLS) and all their patches concatenated
    (n, 4) [a0, a1, z0, z1] (rad, m), each row pointing at its own."""
    rows, pats, off = [], [], 0
    for s in sleeves:
        rows.append(pack_sleeve(s, off))
        pats.append(s.marker.patch_array())
        off += len(pats[-1])
    return np.ascontiguousarray(np.array(rows).reshape(-1, SLEEVE_COLS)), np.ascontiguousarray(np.vstack(pats))


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
    primitives ``prim[ptr[t]:ptr[t + 1]]`` (capsule rows, then n_caps + j = sleeve j), the
    packed capsules and sleeves (k, SLEEVE_COLS), the sleeves' patches (n, 4) and ``box``, the
    pixel rectangle (u0, v0, u1, v1) of the tiles within the image."""

    tiles: NDArray[np.int64]
    ptr: NDArray[np.int64]
    prim: NDArray[np.int64]
    caps: Array
    sleeves: Array
    patches: Array
    box: Box


def plan_arm(
    ray_map: RayMap, capsules: list[Capsule], sleeve: Sleeve | Sequence[Sleeve], ss: int, arm_ss: int
) -> ArmPlan | None:
    """Cull the primitives (camera frame) per tile: the capsules of one or several arms and
    their sleeves (one, or a sequence: sleeve j is primitive n_caps + j). Tiles of any sleeve's
    box get ``ss`` samples per pixel axis, the rest of the arms ``arm_ss``. None if nothing is
    in view."""
    sleeves = [sleeve] if isinstance(sleeve, Sleeve) else list(sleeve)
    if not sleeves:
        raise InputError("plan_arm needs at least one sleeve")
    caps = pack_capsules(capsules)
    bounds = [_sleeve_bounds(s) for s in sleeves]
    lo = np.array([np.zeros(2) if b is None else b[0] for b in bounds])
    hi = np.array([np.zeros(2) if b is None else b[1] for b in bounds])
    seen = np.array([b is not None for b in bounds])
    mask = cull_tiles(ray_map.tile_c, ray_map.tile_r, ray_map.tile_lo, ray_map.tile_hi, caps, lo, hi, seen)
    used = mask.any(axis=2)
    if not used.any():
        return None
    js, is_ = np.nonzero(used)
    tss = np.full(len(js), arm_ss, np.int64)
    if ss == arm_ss:
        tss[:] = ss
    else:  # each marker and what surrounds it at full supersampling
        for b in bounds:
            mbox = None if b is None else ray_map.tiles_box(*b)
            if mbox is not None:
                inside = ((is_ >= mbox[0] // TILE) & (is_ < mbox[2] // TILE) & (js >= mbox[1] // TILE)
                          & (js < mbox[3] // TILE))
                tss[inside] = ss
    sub = mask[js, is_]
    ptr = np.concatenate([[0], np.cumsum(sub.sum(axis=1))]).astype(np.int64)
    prim = np.nonzero(sub)[1].astype(np.int64)
    w, h = ray_map.size
    u1, v1 = min(w, (int(is_.max()) + 1) * TILE), min(h, (int(js.max()) + 1) * TILE)
    box = (int(is_.min()) * TILE, int(js.min()) * TILE, u1, v1)
    tiles = np.column_stack([js, is_, tss]).astype(np.int64)
    rows, patches = pack_sleeves(sleeves)
    return ArmPlan(tiles, ptr, prim, caps, rows, patches, box)


def hidden_points(points: Array, capsules: list[Capsule], sleeves: Sequence[Sleeve]) -> NDArray[np.bool_]:
    """For points (n, 3) [m] in a camera frame, whether the segment from the camera centre to
    each one hits one of the primitives (capsules, sleeves; same frame) nearer than the point:
    what the ray casting draws there instead (the exact intersections of the kernels)."""
    P = np.asarray(points, float).reshape(-1, 3)
    n = len(P)
    hidden = np.zeros(n, np.bool_)
    if n == 0 or (not capsules and not sleeves):
        return hidden
    dist = np.linalg.norm(P, axis=1)
    d = np.ascontiguousarray((P / dist[:, None]).T)
    caps = pack_capsules(capsules)
    rows, _ = pack_sleeves(sleeves) if sleeves else (np.zeros((0, SLEEVE_COLS)), None)
    prim = np.arange(len(caps) + len(rows), dtype=np.int64)
    best, who, surf = np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64)
    trace(prim, 0, len(prim), caps, rows, d[0], d[1], d[2], n, best, who, surf)
    hidden[:] = best < dist
    return hidden


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
    """Ray-cast ``plan`` and blend the arms over the background radiance already in ``out``
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
            ray_map.xy, ray_map.dirs, plan.tiles, plan.ptr, plan.prim, plan.caps, plan.sleeves, plan.patches,
            _MATS if mats is None else mats, float(gain), bool(flat), bool(adaptive), out, int(origin[0]),
            int(origin[1]),
        )
    )
