"""Ray casting of the distal arm (tube, rigid link, marker sleeve, gripper) in one camera.

Rays leave the camera centre through raw (distorted) pixel positions: a per-camera map of
normalized image coordinates, computed once with the camera's exact inverse distortion, is
interpolated at the supersample positions, so the checker corners appear where
``Camera.project`` puts them. Primitives live in the camera frame [m]: capsules (tube pieces,
link, gripper) and the marker sleeve (a finite cylinder with the exact checker pattern of
:meth:`MarkerModel.is_black`). Shading: coaxial light (light at the camera), Lambert plus a
specular lobe, inverse-square falloff.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from cvs.camera import Camera
from cvs.marker import MarkerModel

Array = NDArray[np.float64]
TILE = 32  # tile size of the culling grid [px]
NEAR = 0.01  # near clipping distance along the optical axis [m]
D0 = 0.08  # distance at which the light gives unit irradiance [m]
# Per-ray arithmetic runs in float32 (half the memory traffic of float64); geometry constants
# stay float64 and are cast per primitive. float32 keeps ~1e-7 relative precision: 1e-4 px of
# ray direction at f = 1000 px and nanometres along a ray at 80 mm, far below the corner truth.
RAY = np.float32


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
    tiles plus a 1 px border, and per-tile bounds (box, centre, radius) used for culling."""

    def __init__(self, camera: Camera, image_size: tuple[int, int]) -> None:
        w, h = image_size
        ty, tx = -(-h // TILE), -(-w // TILE)
        u, v = np.meshgrid(np.arange(-1.0, tx * TILE + 1.0), np.arange(-1.0, ty * TILE + 1.0))
        xy = camera.undistort(np.column_stack([u.ravel(), v.ravel()]))
        self.size = (w, h)
        self.tiles = (ty, tx)
        self.xy = xy.reshape(ty * TILE + 2, tx * TILE + 2, 2).astype(np.float64)
        blk = self.xy[1:-1, 1:-1].reshape(ty, TILE, tx, TILE, 2).transpose(0, 2, 1, 3, 4).reshape(ty, tx, -1, 2)
        self.tile_lo, self.tile_hi = blk.min(axis=2), blk.max(axis=2)
        self.tile_c = 0.5 * (self.tile_lo + self.tile_hi)
        self.tile_r = np.linalg.norm(blk - self.tile_c[:, :, None, :], axis=3).max(axis=2)
        d = np.concatenate([blk, np.ones(blk.shape[:3] + (1,))], axis=3)
        self.tile_dirs = (d / np.linalg.norm(d, axis=3, keepdims=True)).astype(RAY)  # (ty, tx, TILE^2, 3)

    def tiles_box(self, lo: Array, hi: Array) -> tuple[int, int, int, int] | None:
        """Pixel rectangle (u0, v0, u1, v1) of the tiles whose rays overlap the normalized box."""
        hit = np.all((self.tile_hi >= lo) & (self.tile_lo <= hi), axis=2)
        if not hit.any():
            return None
        js, is_ = np.nonzero(hit)
        return (int(is_.min()) * TILE, int(js.min()) * TILE, (int(is_.max()) + 1) * TILE, (int(js.max()) + 1) * TILE)

    def directions(self, box: tuple[int, int, int, int], ss: int) -> Array:
        """Unit ray directions (H ss, W ss, 3) at the supersample positions of pixel box
        (u0, v0, u1, v1): sample j of pixel p lies at p - 1/2 + (j + 1/2) / ss."""
        u0, v0, u1, v1 = box
        crop = self.xy[v0 : v1 + 2, u0 : u1 + 2]  # one pixel of border on each side
        big: Any
        if ss == 1:
            big = crop[1:-1, 1:-1]
        else:
            big = cv2.resize(crop, ((u1 - u0 + 2) * ss, (v1 - v0 + 2) * ss), interpolation=cv2.INTER_LINEAR)
            big = big[ss : ss + (v1 - v0) * ss, ss : ss + (u1 - u0) * ss]
        d = np.concatenate([big, np.ones(big.shape[:2] + (1,))], axis=2)
        return (d / np.linalg.norm(d, axis=2, keepdims=True)).astype(RAY)


def _segment_tiles(ray_map: RayMap, P0: Array, P1: Array, rn: float) -> NDArray[np.bool_]:
    """Tiles whose rays come within ``rn`` of the normalized-plane segment P0-P1."""
    c = ray_map.tile_c
    d = P1 - P0
    L2 = float(d @ d)
    k = np.clip(((c - P0) @ d) / L2, 0.0, 1.0) if L2 > 0 else np.zeros(c.shape[:2])
    dist = np.linalg.norm(c - (P0 + k[..., None] * d), axis=2)
    out: NDArray[np.bool_] = dist <= ray_map.tile_r + rn
    return out


def _capsule_bounds(c: Capsule) -> tuple[Array, Array] | None:
    a, b = np.asarray(c.a, float), np.asarray(c.b, float)
    if a[2] < NEAR and b[2] < NEAR:
        return None
    if a[2] < NEAR or b[2] < NEAR:  # clip at the near plane
        s = (NEAR - a[2]) / (b[2] - a[2])
        p = a + s * (b - a)
        a, b = (p, b) if a[2] < NEAR else (a, p)
    P = np.array([a[:2] / a[2], b[:2] / b[2]])
    zmin = min(a[2], b[2])
    widen = 1.2 + float((P**2).sum(axis=1).max())  # off-axis spheres project elongated
    m = widen * c.r / (zmin - c.r) if zmin > c.r * 1.5 else 10.0
    return P, np.array([m])


def _sleeve_bounds(s: Sleeve) -> tuple[Array, Array] | None:
    ang = np.linspace(0, 2 * np.pi, 33)
    h = s.marker.row_height
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)]) * s.marker.radius
    pts = np.vstack([ring + [0, 0, h], ring - [0, 0, h]]) @ s.T_cam_marker[:3, :3].T + s.T_cam_marker[:3, 3]
    if np.any(pts[:, 2] < NEAR):
        return None
    P = pts[:, :2] / pts[:, 2:3]
    m = 0.02 * s.marker.radius / pts[:, 2].min()
    return P.min(axis=0) - m, P.max(axis=0) + m


def _hit_capsule(D: Array, c: Capsule) -> Array:
    """Distances t along unit rays D (..., 3) from the origin to the capsule (inf = miss)."""
    a, b, r = np.asarray(c.a, float), np.asarray(c.b, float), c.r
    ba = b - a
    baba, baoa, oaoa = float(ba @ ba), float(-(ba @ a)), float(a @ a)
    a32, ba32, b32 = a.astype(D.dtype), ba.astype(D.dtype), b.astype(D.dtype)
    bard, rdoa = D @ ba32, -(D @ a32)
    qa = baba - bard * bard
    qb = baba * rdoa - baoa * bard
    qc = baba * oaoa - baoa * baoa - r * r * baba
    h = qb * qb - qa * qc
    ok = (h >= 0) & (qa > 1e-300)
    with np.errstate(invalid="ignore", divide="ignore"):
        tb = (-qb - np.sqrt(np.where(ok, h, 0.0))) / np.where(ok, qa, 1.0)
        y = baoa + tb * bard
        t = np.where(ok & (y > 0) & (y < baba) & (tb > 0), tb, np.inf)
        for end, cb, use in ((a32, rdoa, c.caps[0]), (b32, None, c.caps[1])):  # spherical ends
            if not use:
                continue
            cb = -(D @ end) if cb is None else cb
            ch = cb * cb - float(end.astype(float) @ end.astype(float) - r * r)
            tc = -cb - np.sqrt(np.maximum(ch, 0.0))
            t = np.where((ch >= 0) & (tc > 0) & (tc < t), tc, t)
    return t


def capsule_normals(P: Array, c: Capsule) -> Array:
    """Outward unit normals at surface points P (N, 3) of the capsule (camera frame)."""
    a, ba = np.asarray(c.a, float), np.asarray(c.b, float) - np.asarray(c.a, float)
    k = np.clip(((P - a) @ ba) / (ba @ ba), 0.0, 1.0)
    return (P - (a + k[:, None] * ba)) / c.r


def _hit_sleeve(D: Array, s: Sleeve) -> tuple[Array, Array, NDArray[np.bool_]]:
    """Distances, unit normals (camera frame) and black mask of rays hitting the sleeve."""
    R, p = s.T_cam_marker[:3, :3], s.T_cam_marker[:3, 3]
    o = (-(R.T @ p)).astype(D.dtype)  # camera centre in {wm}
    o0, o1, o2 = (float(x) for x in -(R.T @ p))
    d = D @ R.astype(D.dtype)  # directions in {wm}
    rad, hh = s.marker.radius, s.marker.row_height
    qa = d[..., 0] ** 2 + d[..., 1] ** 2
    qb = o0 * d[..., 0] + o1 * d[..., 1]
    qc = o0**2 + o1**2 - rad * rad
    h = qb * qb - qa * qc
    t = np.full(D.shape[:-1], np.inf, D.dtype)
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = (-qb - np.sqrt(np.maximum(h, 0.0))) / qa
    z = o2 + tc * d[..., 2]
    side = (h >= 0) & (qa > 1e-300) & (tc > 0) & (np.abs(z) < hh)
    t[side] = tc[side]
    q = o + d * np.where(side, tc, 0.0)[..., None]
    n_m = np.stack([q[..., 0] / rad, q[..., 1] / rad, np.zeros_like(z)], axis=-1)
    ang = np.mod(np.arctan2(q[..., 1], q[..., 0]), 2 * np.pi)
    k = np.floor(ang / s.marker.beta).astype(np.int64) % s.marker.columns
    black: NDArray[np.bool_] = ((k % 2) == 0) == (z > 0)
    for zc, nz in ((hh, 1.0), (-hh, -1.0)):  # flat end rings, dark metal
        if abs(d[..., 2]).max() == 0:
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            te = (zc - o2) / d[..., 2]
        qe = o + d * np.where(np.isfinite(te), te, 0.0)[..., None]
        ring = (te > 0) & (te < t) & (qe[..., 0] ** 2 + qe[..., 1] ** 2 <= rad * rad) & (nz * d[..., 2] < 0)
        t[ring] = te[ring]
        n_m[ring] = [0.0, 0.0, nz]
        black[ring] = True
    return t, n_m @ R.T.astype(D.dtype), black


@dataclass
class ArmLayer:
    """The arm rendered into a pixel box at ``ss`` supersamples: BGR radiance [grey levels,
    unclipped] and coverage (True where a ray hit the arm), both (H ss, W ss, ...)."""

    box: tuple[int, int, int, int]
    ss: int
    radiance: NDArray[np.float32]
    hit: NDArray[np.bool_]


MATERIALS = (TUBE, METAL, MARKER_BLACK, MARKER_WHITE)
_ALBEDO = np.array([m.albedo for m in MATERIALS])
_SPEC = np.array([m.specular for m in MATERIALS])
_SHIN = np.array([m.shininess for m in MATERIALS])


def _shade(D: Array, t: Array, N: Array, albedo: Array, spec: Array, shin: Array, gain: float) -> Array:
    ndv = np.clip(-(N * D).sum(axis=-1), 0.0, 1.0)
    fall = (D0 / np.where(np.isfinite(t), t, 1.0)) ** 2
    diffuse = albedo * (0.06 + 0.94 * ndv)[..., None]
    specular = (spec * ndv**shin)[..., None]
    return gain * fall[..., None] * (diffuse + specular)


def sleeve_box(ray_map: RayMap, sleeve: Sleeve) -> tuple[int, int, int, int] | None:
    """Tile-aligned pixel box (u0, v0, u1, v1) that holds the marker sleeve, or None if unseen."""
    bnd = _sleeve_bounds(sleeve)
    return None if bnd is None else ray_map.tiles_box(*bnd)


def render_arm(
    ray_map: RayMap,
    capsules: list[Capsule],
    sleeve: Sleeve,
    ss: int,
    gain: float,
    clip: tuple[int, int, int, int] | None = None,
    exclude: tuple[int, int, int, int] | None = None,
) -> ArmLayer | None:
    """Ray-cast the primitives (camera frame) into the tiles they may cover, optionally only
    within the tile-aligned pixel box ``clip`` and outside ``exclude``; returns the layer over the tiles' bounding box.

    Buffers are tile-major so each primitive touches only its own tiles (tight culling)."""
    ty, tx = ray_map.tiles
    allowed = np.ones((ty, tx), bool)
    if clip is not None:
        allowed[:] = False
        allowed[clip[1] // TILE : -(-clip[3] // TILE), clip[0] // TILE : -(-clip[2] // TILE)] = True
    if exclude is not None:  # tiles another pass renders (e.g. the marker at higher supersampling)
        allowed[exclude[1] // TILE : -(-exclude[3] // TILE), exclude[0] // TILE : -(-exclude[2] // TILE)] = False
    work: list[tuple[Capsule | Sleeve, NDArray[np.bool_]]] = []
    prims: list[Capsule | Sleeve] = [*capsules, sleeve]
    for prim in prims:
        if isinstance(prim, Capsule):
            bnd = _capsule_bounds(prim)
            if bnd is None:
                continue
            sel = _segment_tiles(ray_map, bnd[0][0], bnd[0][1], float(bnd[1][0])) & allowed
        else:
            sb = _sleeve_bounds(prim)
            if sb is None:
                continue
            sel = np.all((ray_map.tile_hi >= sb[0]) & (ray_map.tile_lo <= sb[1]), axis=2) & allowed
        if sel.any():
            work.append((prim, sel))
    if not work:
        return None
    used = np.any([w for _, w in work], axis=0)
    js, is_ = np.nonzero(used)
    j0, j1, i0, i1 = int(js.min()), int(js.max()) + 1, int(is_.min()), int(is_.max()) + 1
    roi = (i0 * TILE, j0 * TILE, i1 * TILE, j1 * TILE)
    n = TILE * ss
    if ss == 1:
        D = ray_map.tile_dirs[j0:j1, i0:i1].reshape(-1, n * n, 3)
    else:
        D = ray_map.directions(roi, ss).reshape(j1 - j0, n, i1 - i0, n, 3).transpose(0, 2, 1, 3, 4)
        D = D.reshape((j1 - j0) * (i1 - i0), n * n, 3)
    nt = D.shape[0]
    depth = np.full((nt, n * n), np.inf, RAY)
    normal = np.zeros((nt, n * n, 3), RAY)
    mat = np.zeros((nt, n * n), np.int8)
    pid = np.full((nt, n * n), -1, np.int32)
    for i, (prim, sel) in enumerate(work):
        idx = (np.nonzero(sel[j0:j1, i0:i1].ravel()))[0]
        Db = D[idx]
        dcur = depth[idx]
        if isinstance(prim, Capsule):
            t = _hit_capsule(Db, prim)
            m = t < dcur
            mid: NDArray[np.int8] | int = MATERIALS.index(prim.material)
        else:
            t, N, black = _hit_sleeve(Db, prim)
            m = t < dcur
            mid = np.where(black, 2, 3).astype(np.int8)
            normal[idx] = np.where(m[..., None], N, normal[idx])
        if not m.any():
            continue
        depth[idx] = np.where(m, t, dcur)
        mat[idx] = np.where(m, mid, mat[idx])
        pid[idx] = np.where(m, i, pid[idx])
    hit = np.isfinite(depth)
    hidx = np.flatnonzero(hit)
    owner = pid.ravel()[hidx]
    order = np.argsort(owner, kind="stable")
    hidx, owner = hidx[order], owner[order]
    cuts = np.searchsorted(owner, np.arange(len(work) + 1))
    Df, tf, Nf = D.reshape(-1, 3), depth.ravel(), normal.reshape(-1, 3)
    for i, (prim, _) in enumerate(work):  # capsule normals only where they are seen
        if isinstance(prim, Capsule) and cuts[i + 1] > cuts[i]:
            seg = hidx[cuts[i] : cuts[i + 1]]
            Nf[seg] = capsule_normals(Df[seg] * tf[seg, None], prim)
    rad = np.zeros((nt, n * n, 3), np.float32)
    mh = mat.ravel()[hidx]
    rad.reshape(-1, 3)[hidx] = _shade(Df[hidx], tf[hidx], Nf[hidx], _ALBEDO[mh], _SPEC[mh], _SHIN[mh], gain)

    def image(a: np.ndarray) -> np.ndarray:
        a = a.reshape(j1 - j0, i1 - i0, n, n, *a.shape[2:]).swapaxes(1, 2)
        return a.reshape((j1 - j0) * n, (i1 - i0) * n, *a.shape[4:])

    return ArmLayer(roi, ss, image(rad).astype(np.float32), image(hit))
