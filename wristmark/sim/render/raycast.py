"""Numba kernels of the arm's ray caster: ray-primitive intersection, supersample positions,
adaptive supersampling, shading and blending over the background, in place.

All geometry is in one camera's frame [m]. Rays leave the camera centre through raw
(distorted) pixel positions looked up (bilinearly) in the camera's normalized-coordinate map
``xy``: entry ``xy[v + 1, u + 1]`` holds (x/z, y/z) of raw pixel (u, v). Sample j (0..ss-1) of
pixel p along each axis lies at ``p - 1/2 + (j + 1/2) / ss``. Rays are traced in batches held
as three arrays (structure of arrays), each primitive against a whole batch in one
branch-free loop that the compiler vectorizes (SIMD).

Packed primitives (float64 rows, built by :mod:`sim.render.arm`):

- capsule (CAPSULE_COLS): ``a(3) b(3) r cap_a cap_b material ba(3) |ba|^2 -ba.a a.a``, the
  cylinder from a to b of radius r with spherical ends where cap_a / cap_b are non-zero;
- sleeve (SLEEVE_COLS): ``R(9, row-major: {wm} in the camera) o(3) (camera centre in {wm})
  radius row_height columns beta z_lo z_hi pat_lo pat_hi``: the side z_lo < z < z_hi of the
  cylinder of ``radius`` around z_wm with the colours of
  :meth:`models.marker.MarkerModel.is_black` (the checker rows |z| < row_height, then its dark
  patches, rows ``pat_lo <= k < pat_hi`` of ``pat`` (``a0 a1 z0 z1`` [rad, m]), white
  elsewhere), and its two flat end rings (black), facing outwards.

Several arms are drawn at once: ``sleeves`` holds one row per arm's sleeve (k, SLEEVE_COLS)
and ``pat`` the patches of all of them, concatenated. Primitive index q < n_caps is capsule
row q (of any arm), q >= n_caps is sleeve q - n_caps; the nearest hit over all of them wins,
which gives the arms' mutual occlusion.

Materials (rows of ``mats``): albedo B, G, R in [0, 1], specular strength, shininess; ids 0
tube, 1 metal, 2 marker black, 3 marker white. Shading: coaxial light at the camera, ambient
0.06 + Lambert 0.94 plus a specular lobe ``spec * (n.v)^shin``, inverse-square falloff with
unit irradiance at ``D0``; ``flat`` shades albedo only (geometry tests). A glossy sleeve
(optional rows from ``GLOSS_ROW``: F0 and GGX alpha, then the light outputs' positions in the
camera frame [m] and weights) adds the laminate's specular lobe of each light output on both
patch colours (:func:`_laminate`); without those rows the shading is exactly the matte one.

Kernels are compiled with ``cache=True`` (paid once per machine) and ``nogil=True`` (the two
cameras render in parallel threads), without ``parallel=True`` (the two cores are already
busy); ``error_model="numpy"`` lets a division by zero give inf, masked out where it matters.
They use only names of this file: numba's on-disk cache does not notice changes in others.
Tiles at one sample per pixel trace their precomputed centre rays (:func:`ray_directions`) in
one batch and write the hit's radiance directly (the mean of one sample); the per-ray helpers
are inlined (``jit_inline``) and no array view is made per pixel: a call or a view that holds
arrays pays their atomic reference counts, which cost more than the helpers' arithmetic
(measured: ray casting of a 1080p view 18 -> 11 ms, images unchanged).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

TILE = 32  # tile size of the culling grid [px]
CAPSULE_COLS = 16
SLEEVE_COLS = 20
SIDE, RING_TOP, RING_BOTTOM = 0, 2, 3  # sleeve surfaces hit (the side's colour comes later)

D0 = 0.08  # distance at which the light gives unit irradiance [m]
MAT_BLACK, MAT_WHITE = 2, 3
GLOSS_ROW = 4  # ``mats`` row of the sleeve's glossy laminate (F0, alpha), then one row per light output
BATCH = 2048  # rays traced together (fits the L1/L2 caches)
RING = TILE + 2  # centre rays of a tile plus a 1 px ring, for adaptive supersampling
# Largest |f_uu| + |f_vv| (second differences of the centre rays' radiance [grey levels]) for
# which a pixel keeps its centre ray: the pixel mean differs from the centre value by about
# (1 - 1/ss^2) / 24 of that, i.e. < 0.05 grey levels.
CURVATURE = 1.2

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
jit = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")
# per-ray helpers inlined into their callers in numba's IR: a call that passes arrays pays their
# reference counts (atomic operations), more than the helper's own work
jit_inline = numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy", inline="always")


@jit
def hit_capsule(caps: F64, q: int, dx: F64, dy: F64, dz: F64, n: int, best: F64, who: I64) -> None:
    """Rays 0..n-1 (unit directions dx, dy, dz) against capsule row q: where it is hit nearer
    than ``best`` [m], set ``best`` to the distance and ``who`` to q."""
    ax, ay, az, bx, by, bz = caps[q, 0], caps[q, 1], caps[q, 2], caps[q, 3], caps[q, 4], caps[q, 5]
    bax, bay, baz, baba, baoa, oaoa = caps[q, 10], caps[q, 11], caps[q, 12], caps[q, 13], caps[q, 14], caps[q, 15]
    r2 = caps[q, 6] * caps[q, 6]
    cap_a, cap_b = caps[q, 7] != 0.0, caps[q, 8] != 0.0
    qc = baba * oaoa - baoa * baoa - r2 * baba
    ca = oaoa - r2
    cb_ = bx * bx + by * by + bz * bz - r2
    for i in range(n):
        bard = dx[i] * bax + dy[i] * bay + dz[i] * baz
        rdoa = -(dx[i] * ax + dy[i] * ay + dz[i] * az)
        qa = baba - bard * bard
        qb = baba * rdoa - baoa * bard
        h = qb * qb - qa * qc
        num = -qb - math.sqrt(max(h, 0.0))  # near root of the infinite cylinder: num / qa
        y = baoa * qa + num * bard  # its axial coordinate times qa
        okq = qa > 1e-300
        tcyl = num / (qa if okq else 1.0)
        ok = (h >= 0.0) & okq & (y > 0.0) & (y < baba * qa) & (num > 0.0)
        t = tcyl if ok else math.inf
        ch = rdoa * rdoa - ca  # sphere at a
        tc = -rdoa - math.sqrt(max(ch, 0.0))
        t = tc if (cap_a & (ch >= 0.0) & (tc > 0.0) & (tc < t)) else t
        cb = -(dx[i] * bx + dy[i] * by + dz[i] * bz)  # sphere at b
        ch = cb * cb - cb_
        tc = -cb - math.sqrt(max(ch, 0.0))
        t = tc if (cap_b & (ch >= 0.0) & (tc > 0.0) & (tc < t)) else t
        b = best[i]
        m = t < b
        best[i] = t if m else b
        who[i] = q if m else who[i]


@jit
def hit_sleeve(sleeves: F64, j: int, q: int, dx: F64, dy: F64, dz: F64, n: int, best: F64, who: I64,
               surf: I64) -> None:
    """Rays 0..n-1 against sleeve row j (primitive index q): where it is hit nearer than
    ``best`` [m], set ``best``, ``who`` = q and ``surf`` (SIDE, RING_TOP at z = z_hi or
    RING_BOTTOM at z = z_lo)."""
    s = sleeves[j]  # one view per batch (not per ray)
    o0, o1, o2, rad, zlo, zhi = s[9], s[10], s[11], s[12], s[16], s[17]
    qc = o0 * o0 + o1 * o1 - rad * rad
    for i in range(n):
        d0 = s[0] * dx[i] + s[3] * dy[i] + s[6] * dz[i]  # direction in {wm}: R^T d
        d1 = s[1] * dx[i] + s[4] * dy[i] + s[7] * dz[i]
        d2 = s[2] * dx[i] + s[5] * dy[i] + s[8] * dz[i]
        qa = d0 * d0 + d1 * d1
        qb = o0 * d0 + o1 * d1
        h = qb * qb - qa * qc
        okq = qa > 1e-300
        tc = (-qb - math.sqrt(max(h, 0.0))) / (qa if okq else 1.0)
        z = o2 + tc * d2
        side = (h >= 0.0) & okq & (tc > 0.0) & (z > zlo) & (z < zhi)
        t = tc if side else math.inf
        code = SIDE
        nz0 = d2 != 0.0
        dd = d2 if nz0 else 1.0
        te = (zhi - o2) / dd  # end ring at z = z_hi, seen from above (d2 < 0)
        qx, qy = o0 + te * d0, o1 + te * d1
        ring = nz0 & (te > 0.0) & (te < t) & (qx * qx + qy * qy <= rad * rad) & (d2 < 0.0)
        t = te if ring else t
        code = RING_TOP if ring else code
        te = (zlo - o2) / dd  # end ring at z = z_lo, seen from below (d2 > 0)
        qx, qy = o0 + te * d0, o1 + te * d1
        ring = nz0 & (te > 0.0) & (te < t) & (qx * qx + qy * qy <= rad * rad) & (d2 > 0.0)
        t = te if ring else t
        code = RING_BOTTOM if ring else code
        b = best[i]
        m = t < b
        best[i] = t if m else b
        who[i] = q if m else who[i]
        surf[i] = code if m else surf[i]


@jit
def trace(
    prim: I64, p0: int, p1: int, caps: F64, sleeves: F64, dx: F64, dy: F64, dz: F64, n: int,
    best: F64, who: I64, surf: I64,
) -> None:
    """Nearest hit of rays 0..n-1 among primitives ``prim[p0:p1]`` (capsule rows; n_caps + j:
    sleeve row j): distance ``best`` [m] (inf: none), primitive ``who`` (-1: none), sleeve
    ``surf``."""
    nc = caps.shape[0]
    for i in range(n):
        best[i] = math.inf
        who[i] = -1
        surf[i] = SIDE
    for k in range(p0, p1):
        q = prim[k]
        if q < nc:
            hit_capsule(caps, q, dx, dy, dz, n, best, who)
        else:
            hit_sleeve(sleeves, q - nc, q, dx, dy, dz, n, best, who, surf)


@jit_inline
def _ray(xy: F64, fu: float, fv: float) -> tuple[float, float, float]:
    """Unit direction of the ray through raw pixel position (fu, fv) [px] (bilinear map lookup)."""
    gx, gy = fu + 1.0, fv + 1.0
    iu = min(int(math.floor(gx)), xy.shape[1] - 2)
    iv = min(int(math.floor(gy)), xy.shape[0] - 2)
    au, av = gx - iu, gy - iv
    w00, w01, w10, w11 = (1 - av) * (1 - au), (1 - av) * au, av * (1 - au), av * au
    x = w00 * xy[iv, iu, 0] + w01 * xy[iv, iu + 1, 0] + w10 * xy[iv + 1, iu, 0] + w11 * xy[iv + 1, iu + 1, 0]
    y = w00 * xy[iv, iu, 1] + w01 * xy[iv, iu + 1, 1] + w10 * xy[iv + 1, iu, 1] + w11 * xy[iv + 1, iu + 1, 1]
    n = math.sqrt(x * x + y * y + 1.0)
    return x / n, y / n, 1.0 / n


@jit_inline
def sleeve_dark(sleeves: F64, j: int, pat: F64, ang: float, z: float) -> bool:
    """Is sleeve row j dark at angle ``ang`` in [0, 2 pi) [rad] and height z [m]: a checker
    patch (|z| < row_height) or one of its patches (rows pat_lo..pat_hi-1 of ``pat``: a0 a1 z0 z1)."""
    if abs(z) < sleeves[j, 13]:
        col = int(math.floor(ang / sleeves[j, 15])) % int(sleeves[j, 14])
        if ((col % 2) == 0) == (z > 0.0):
            return True
    for k in range(int(sleeves[j, 18]), int(sleeves[j, 19])):
        if pat[k, 2] <= z < pat[k, 3] and (ang - pat[k, 0]) % (2.0 * math.pi) < pat[k, 1] - pat[k, 0]:
            return True
    return False


@jit_inline
def _laminate(px: float, py: float, pz: float, nx: float, ny: float, nz: float, t: float, mats: F64) -> float:
    """Specular radiance of the sleeve's glossy laminate at point p (normal n) seen from the
    camera centre at distance t [m], relative to the coaxial light's unit irradiance at D0:
    for each light output (rows GLOSS_ROW + 1.. of ``mats``: position x, y, z [m], weight) a
    GGX (Trowbridge-Reitz) lobe ``pi F0 D(n.h) / (4 n.v)`` (roughness alpha, Fresnel F0 at
    normal incidence, shadowing ~1 near the highlight) times the output's irradiance relative to
    the coaxial light's, ``weight (t / |l|)^2 (n.l)``."""
    f0, a2 = mats[GLOSS_ROW, 0], mats[GLOSS_ROW, 1] * mats[GLOSS_ROW, 1]
    vx, vy, vz = -px / t, -py / t, -pz / t
    ndv = max(nx * vx + ny * vy + nz * vz, 1e-3)
    out = 0.0
    for k in range(GLOSS_ROW + 1, mats.shape[0]):
        lx, ly, lz = mats[k, 0] - px, mats[k, 1] - py, mats[k, 2] - pz
        dl = math.sqrt(lx * lx + ly * ly + lz * lz)
        lx, ly, lz = lx / dl, ly / dl, lz / dl
        ndl = nx * lx + ny * ly + nz * lz
        if ndl <= 0.0:
            continue
        hx, hy, hz = lx + vx, ly + vy, lz + vz
        hn = math.sqrt(hx * hx + hy * hy + hz * hz)
        ndh = (nx * hx + ny * hy + nz * hz) / hn
        den = ndh * ndh * (a2 - 1.0) + 1.0
        d = a2 / (math.pi * den * den)
        out += mats[k, 3] * (t / dl) ** 2 * ndl * math.pi * f0 * d / (4.0 * ndv)
    return out


@jit_inline
def _shade(
    dx: float, dy: float, dz: float, t: float, q: int, code: int, caps: F64, sleeves: F64, pat: F64, mats: F64,
    gain: float, flat: bool,
) -> tuple[int, float, float, float]:
    """Surface key and B, G, R radiance [grey levels] of a ray (unit direction) hitting
    primitive q at distance t [m] (sleeve surface ``code``). Keys: 4 q for capsule q, 4 q +
    (0 white patch, 1 black patch, 2 / 3 end ring) for sleeve q - n_caps."""
    nc = caps.shape[0]
    if q < nc:  # capsule: normal from the nearest axis point
        px, py, pz = dx * t - caps[q, 0], dy * t - caps[q, 1], dz * t - caps[q, 2]
        k = min(max((px * caps[q, 10] + py * caps[q, 11] + pz * caps[q, 12]) / caps[q, 13], 0.0), 1.0)
        r = caps[q, 6]
        nx, ny, nz = (px - k * caps[q, 10]) / r, (py - k * caps[q, 11]) / r, (pz - k * caps[q, 12]) / r
        mat, key = int(caps[q, 9]), 4 * q
    else:  # sleeve row j: hit point in {wm}, checker colour on the side
        j = q - nc
        d0 = sleeves[j, 0] * dx + sleeves[j, 3] * dy + sleeves[j, 6] * dz
        d1 = sleeves[j, 1] * dx + sleeves[j, 4] * dy + sleeves[j, 7] * dz
        d2 = sleeves[j, 2] * dx + sleeves[j, 5] * dy + sleeves[j, 8] * dz
        m0, m1, m2 = 0.0, 0.0, (1.0 if code == RING_TOP else -1.0)
        surf = code
        if code == SIDE:
            q0, q1, z = sleeves[j, 9] + t * d0, sleeves[j, 10] + t * d1, sleeves[j, 11] + t * d2
            m0, m1, m2 = q0 / sleeves[j, 12], q1 / sleeves[j, 12], 0.0
            a = math.atan2(q1, q0)  # in [-pi, pi]: the same as a % (2 pi), without its fmod
            surf = 1 if sleeve_dark(sleeves, j, pat, a if a >= 0.0 else a + 2.0 * math.pi, z) else 0
        nx = sleeves[j, 0] * m0 + sleeves[j, 1] * m1 + sleeves[j, 2] * m2  # normal to the camera frame: R m
        ny = sleeves[j, 3] * m0 + sleeves[j, 4] * m1 + sleeves[j, 5] * m2
        nz = sleeves[j, 6] * m0 + sleeves[j, 7] * m1 + sleeves[j, 8] * m2
        mat, key = (MAT_WHITE if surf == 0 else MAT_BLACK), 4 * q + surf
    if flat:
        return key, gain * mats[mat, 0], gain * mats[mat, 1], gain * mats[mat, 2]
    ndv = min(max(-(nx * dx + ny * dy + nz * dz), 0.0), 1.0)
    fall = gain * (D0 / t) ** 2
    lam = 0.06 + 0.94 * ndv
    spec = mats[mat, 3] * ndv ** mats[mat, 4]
    if q >= nc and mats.shape[0] > GLOSS_ROW:  # the sleeve's glossy laminate (RenderSettings.sleeve_specular)
        spec += _laminate(dx * t, dy * t, dz * t, nx, ny, nz, t, mats)
    b, g, r = mats[mat, 0], mats[mat, 1], mats[mat, 2]
    return key, fall * (b * lam + spec), fall * (g * lam + spec), fall * (r * lam + spec)


@jit
def _flush(
    n: int, rays: F64, pix: I64, prim: I64, p0: int, p1: int, caps: F64, sleeves: F64, pat: F64, mats: F64,
    gain: float, flat: bool, best: F64, who: I64, surf: I64, acc: F64, cnt: I64,
) -> None:
    """Trace and shade the batch ``rays[:, :n]``; add radiance and hit counts to the pixels ``pix``."""
    trace(prim, p0, p1, caps, sleeves, rays[0], rays[1], rays[2], n, best, who, surf)
    for i in range(n):
        if who[i] >= 0:
            _, r0, r1, r2 = _shade(rays[0, i], rays[1, i], rays[2, i], best[i], who[i], surf[i], caps, sleeves, pat,
                                   mats, gain, flat)
            p = pix[i]
            acc[p, 0] += r0
            acc[p, 1] += r1
            acc[p, 2] += r2
            cnt[p] += 1


@jit
def _centre_rays(xy: F64, prim: I64, p0: int, p1: int, caps: F64, sleeves: F64, pat: F64, mats: F64, gain: float,
                 flat: bool, tu: int, tv: int, rays: F64, best: F64, who: I64, surf: I64, keys: I64,
                 crad: F64) -> int:
    """Adaptive supersampling's first pass: one ray through the centre of every pixel of the tile
    at (tu, tv) and of a 1 px ring around it; ``keys`` the surface hit (-1: miss), ``crad`` its
    radiance. Returns the rays cast."""
    count = 0
    for c0 in range(0, RING * RING, BATCH):
        n = min(BATCH, RING * RING - c0)
        for i in range(n):
            a, b = (c0 + i) // RING, (c0 + i) % RING
            rays[0, i], rays[1, i], rays[2, i] = _ray(xy, tu + b - 1.0, tv + a - 1.0)
        trace(prim, p0, p1, caps, sleeves, rays[0], rays[1], rays[2], n, best, who, surf)
        for i in range(n):
            a, b = (c0 + i) // RING, (c0 + i) % RING
            keys[a, b] = -1
            if who[i] >= 0:
                keys[a, b], crad[a, b, 0], crad[a, b, 1], crad[a, b, 2] = _shade(
                    rays[0, i], rays[1, i], rays[2, i], best[i], who[i], surf[i], caps, sleeves, pat, mats,
                    gain, flat)
        count += n
    return count


@jit
def _keep_smooth_centres(need: NDArray[np.bool_], keys: I64, crad: F64, out: NDArray[np.float32], tu: int, tv: int,
                         u0: int, v0: int) -> None:
    """Pixels whose 3 x 3 centre rays hit the same surface (or all miss) with nearly linear
    shading take their centre ray's radiance and need no supersampling."""
    for p in range(TILE * TILE):
        if not need[p]:
            continue
        pv, pu = p // TILE, p % TILE
        k0 = keys[pv + 1, pu + 1]
        same = True
        for a in range(3):
            for b in range(3):
                same = same and keys[pv + a, pu + b] == k0
        if same and k0 >= 0:  # and the shading is nearly linear across the pixel
            for c in range(3):
                ctr = 2.0 * crad[pv + 1, pu + 1, c]
                fuu = crad[pv + 1, pu, c] + crad[pv + 1, pu + 2, c] - ctr
                fvv = crad[pv, pu + 1, c] + crad[pv + 2, pu + 1, c] - ctr
                same = same and abs(fuu) + abs(fvv) <= CURVATURE
        if same:
            need[p] = False
            if k0 >= 0:
                for c in range(3):
                    out[tv + pv - v0, tu + pu - u0, c] = crad[pv + 1, pu + 1, c]


@jit
def _supersample(xy: F64, prim: I64, p0: int, p1: int, caps: F64, sleeves: F64, pat: F64, mats: F64, gain: float,
                 flat: bool, tu: int, tv: int, ss: int, need: NDArray[np.bool_], out: NDArray[np.float32], u0: int,
                 v0: int, rays: F64, pix: I64, best: F64, who: I64, surf: I64, acc: F64, cnt: I64) -> int:
    """Full ss x ss supersampling of the tile's pixels that ``need`` it, blended over ``out`` (a
    missing sample keeps the background). Returns the rays cast."""
    inv = 1.0 / ss
    count = 0
    acc[:] = 0.0
    cnt[:] = 0
    n = 0
    for p in range(TILE * TILE):
        if not need[p]:
            continue
        v, u = tv + p // TILE, tu + p % TILE
        for sy in range(ss):
            fv = v - 0.5 + (sy + 0.5) * inv
            for sx in range(ss):
                rays[0, n], rays[1, n], rays[2, n] = _ray(xy, u - 0.5 + (sx + 0.5) * inv, fv)
                pix[n] = p
                n += 1
                if n == BATCH:
                    _flush(n, rays, pix, prim, p0, p1, caps, sleeves, pat, mats, gain, flat, best, who, surf, acc,
                           cnt)
                    count += n
                    n = 0
    _flush(n, rays, pix, prim, p0, p1, caps, sleeves, pat, mats, gain, flat, best, who, surf, acc, cnt)
    count += n
    nss = ss * ss
    for p in range(TILE * TILE):
        if need[p] and cnt[p] > 0:
            a, b = tv + p // TILE - v0, tu + p % TILE - u0
            miss = nss - cnt[p]
            for c in range(3):
                out[a, b, c] = (acc[p, c] + miss * out[a, b, c]) / nss
    return count


@jit
def ray_directions(xy: F64, ty: int, tx: int) -> F64:
    """Unit directions of the rays through the pixel centres, per tile: ``d[j, i, :, p]`` for
    pixel p (row-major) of tile (j, i), as :func:`_ray` gives them (what one sample per pixel
    traces)."""
    d = np.empty((ty, tx, 3, TILE * TILE))
    for j in range(ty):
        for i in range(tx):
            for p in range(TILE * TILE):
                fu, fv = float(i * TILE + p % TILE), float(j * TILE + p // TILE)
                d[j, i, 0, p], d[j, i, 1, p], d[j, i, 2, p] = _ray(xy, fu, fv)
    return d


@jit
def _single_sample(dirs: F64, prim: I64, p0: int, p1: int, caps: F64, sleeves: F64, pat: F64, mats: F64, gain: float,
                   flat: bool, tu: int, tv: int, need: NDArray[np.bool_], out: NDArray[np.float32], u0: int, v0: int,
                   best: F64, who: I64, surf: I64) -> int:
    """One sample per pixel: the tile's centre rays (``dirs`` (3, TILE^2), precomputed) traced in
    one batch; a pixel that ``need`` s it and is hit takes the hit's radiance (what the mean of
    one sample over the background gives), the others keep the background. Returns the rays cast."""
    n = TILE * TILE
    trace(prim, p0, p1, caps, sleeves, dirs[0], dirs[1], dirs[2], n, best, who, surf)
    for p in range(n):
        if need[p] and who[p] >= 0:
            _, r0, r1, r2 = _shade(dirs[0, p], dirs[1, p], dirs[2, p], best[p], who[p], surf[p], caps, sleeves, pat,
                                   mats, gain, flat)
            a, b = tv + p // TILE - v0, tu + p % TILE - u0  # (no view per pixel: its reference count costs)
            out[a, b, 0], out[a, b, 1], out[a, b, 2] = r0, r1, r2
    return n


@jit
def raycast_tiles(
    xy: F64, dirs: F64, tiles: I64, ptr: I64, prim: I64, caps: F64, sleeves: F64, pat: F64, mats: F64, gain: float,
    flat: bool, adaptive: bool, out: NDArray[np.float32], u0: int, v0: int,
) -> int:
    """Ray-cast tiles (rows ``tile_row, tile_col, ss``) against their primitives ``prim[ptr[t]:
    ptr[t + 1]]`` (capsule rows; n_caps + j: sleeve row j) and blend into ``out`` (BGR radiance
    [grey levels], pixel (u, v) at ``out[v - v0, u - u0]``): each pixel becomes the mean of its
    ss x ss samples, the background value where a sample misses.

    ``adaptive``: in tiles with ss > 1, first trace one ray through every pixel centre (and a
    1 px ring around the tile); a pixel whose 3 x 3 neighbourhood of centre rays all hit the
    same surface (same primitive, patch colour or ring; or all miss) and whose shading is nearly
    linear there (second differences below ``CURVATURE``) takes its centre ray's radiance; only
    the others are supersampled. A straight edge crossing a pixel always separates some of its
    3 x 3 centres, so edges, corners and silhouettes keep full supersampling (only features
    thinner than a pixel lying between centres could be missed). Returns the rays cast."""
    h, w = out.shape[0], out.shape[1]
    count = 0
    rays = np.empty((3, BATCH))
    pix = np.empty(BATCH, np.int64)
    best, who, surf = np.empty(BATCH), np.empty(BATCH, np.int64), np.empty(BATCH, np.int64)
    acc, cnt = np.zeros((TILE * TILE, 3)), np.zeros(TILE * TILE, np.int64)
    need = np.empty(TILE * TILE, np.bool_)
    keys, crad = np.empty((RING, RING), np.int64), np.empty((RING, RING, 3))
    for t in range(tiles.shape[0]):
        ss = tiles[t, 2]
        p0, p1 = ptr[t], ptr[t + 1]
        tv, tu = tiles[t, 0] * TILE, tiles[t, 1] * TILE
        for p in range(TILE * TILE):
            v, u = tv + p // TILE, tu + p % TILE
            need[p] = 0 <= v - v0 < h and 0 <= u - u0 < w
        if ss == 1:  # the centre rays, precomputed (``dirs``, from :func:`ray_directions`)
            count += _single_sample(dirs[tiles[t, 0], tiles[t, 1]], prim, p0, p1, caps, sleeves, pat, mats, gain, flat,
                                    tu, tv, need, out, u0, v0, best, who, surf)
            continue
        if adaptive and ss > 1:
            count += _centre_rays(xy, prim, p0, p1, caps, sleeves, pat, mats, gain, flat, tu, tv, rays, best, who,
                                  surf, keys, crad)
            _keep_smooth_centres(need, keys, crad, out, tu, tv, u0, v0)
        count += _supersample(xy, prim, p0, p1, caps, sleeves, pat, mats, gain, flat, tu, tv, ss, need, out, u0, v0,
                              rays, pix, best, who, surf, acc, cnt)
    return count
