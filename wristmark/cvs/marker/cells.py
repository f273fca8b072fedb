"""Numba kernel of the code reading (cvs.marker.decode): grey levels at the projected centres of
the code cells and of their checker references, in one camera.

One call per camera transforms the sleeve points to the camera frame, drops those facing away
(cos_view below the limit), projects the rest with the OpenCV model (distortion [k1, k2, p1,
p2, k3]) and samples the image bilinearly (BGR: luminance 0.114 B + 0.587 G + 0.299 R at the four
neighbours); NaN where not sampled. Numpy costs ~1 ms per stereo pair for these few dozen
points in small operations; the kernel ~20 us.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@numba.njit(cache=True, nogil=True)
def _grey(img: Any, v: int, u: int) -> float:  # pragma: no cover
    if img.ndim == 2:
        return float(img[v, u])
    return 0.114 * img[v, u, 0] + 0.587 * img[v, u, 1] + 0.299 * img[v, u, 2]


@numba.njit(cache=True, nogil=True)
def _pixel(img: Any, X: float, Y: float, Z: float, K: Any, dist: Any) -> float:  # pragma: no cover
    """Bilinear grey level at the projection of camera-frame point (X, Y, Z); NaN outside."""
    if Z <= 0.0:
        return np.nan
    h, w = img.shape[0], img.shape[1]
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    x, y = X / Z, Y / Z
    r2 = x * x + y * y
    rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    u = K[0, 0] * xd + K[0, 1] * yd + K[0, 2]
    v = K[1, 1] * yd + K[1, 2]
    if not (u >= 0.0 and v >= 0.0 and u <= w - 1.001 and v <= h - 1.001):
        return np.nan
    u0, v0 = int(u), int(v)
    fu, fv = u - u0, v - v0
    a = _grey(img, v0, u0) * (1 - fu) + _grey(img, v0, u0 + 1) * fu
    b = _grey(img, v0 + 1, u0) * (1 - fu) + _grey(img, v0 + 1, u0 + 1) * fu
    return a * (1 - fv) + b * fv


@numba.njit(cache=True, nogil=True)
def _sample(img: Any, pts: Any, nrm: Any, T: Any, K: Any, dist: Any, min_cos: float,
            out: Any) -> None:  # pragma: no cover
    for i in range(pts.shape[0]):
        out[i] = np.nan
        X = T[0, 0] * pts[i, 0] + T[0, 1] * pts[i, 1] + T[0, 2] * pts[i, 2] + T[0, 3]
        Y = T[1, 0] * pts[i, 0] + T[1, 1] * pts[i, 1] + T[1, 2] * pts[i, 2] + T[1, 3]
        Z = T[2, 0] * pts[i, 0] + T[2, 1] * pts[i, 1] + T[2, 2] * pts[i, 2] + T[2, 3]
        if Z <= 0.0:
            continue
        nx = T[0, 0] * nrm[i, 0] + T[0, 1] * nrm[i, 1] + T[0, 2] * nrm[i, 2]
        ny = T[1, 0] * nrm[i, 0] + T[1, 1] * nrm[i, 1] + T[1, 2] * nrm[i, 2]
        nz = T[2, 0] * nrm[i, 0] + T[2, 1] * nrm[i, 1] + T[2, 2] * nrm[i, 2]
        if -(nx * X + ny * Y + nz * Z) / math.sqrt(X * X + Y * Y + Z * Z) < min_cos:
            continue
        out[i] = _pixel(img, X, Y, Z, K, dist)


def sample_sleeve(img: NDArray[np.uint8], points: Array, normals: Array, T_cam_marker: Array, K: Array, dist: Array,
                  min_cos: float) -> Array:
    """Grey levels (n,) at sleeve points (n, 3) in {wm} with outward normals (n, 3), seen by a
    camera (K, dist) at T_cam_marker; NaN where facing away (cos_view < min_cos), behind the
    camera or out of the image."""
    out = np.empty(points.shape[0])
    _sample(img, points, normals, np.ascontiguousarray(T_cam_marker, np.float64), K, dist, float(min_cos), out)
    return out


@numba.njit(cache=True, nogil=True)
def _mean_of(v: Any, i: int, j: int, k: int) -> float:  # pragma: no cover
    a, b = v[i], v[j]
    if np.isfinite(a) and np.isfinite(b):
        return 0.5 * (a + b)
    return v[k]  # one neighbour alone is biased by the cylinder's shading: the fallback (module doc)


@numba.njit(cache=True, nogil=True)
def _darkness(vs: Any, n_cells: int, dark_ref: Any, white_ref: Any, min_contrast: float,
              out: Any, phase: int) -> int:  # pragma: no cover
    ncam = vs.shape[0]
    B = np.empty((ncam, n_cells))
    W = np.empty((ncam, n_cells))
    pos = neg = 0
    for c in range(ncam):
        for i in range(n_cells):
            B[c, i] = _mean_of(vs[c], n_cells + dark_ref[i, 0], n_cells + dark_ref[i, 1], n_cells + dark_ref[i, 2])
            W[c, i] = _mean_of(vs[c], n_cells + white_ref[i, 0], n_cells + white_ref[i, 1],
                               n_cells + white_ref[i, 2])
            d = W[c, i] - B[c, i]
            if d > 0:
                pos += 1
            elif d < 0:
                neg += 1
    if phase < 0:  # decided here: the references' own vote
        if pos + neg == 0 or min(pos, neg) > 0.1 * (pos + neg):
            out[:] = np.nan
            return -1
        phase = 0 if pos > neg else 1
    for i in range(n_cells):
        num = den = 0.0
        for c in range(ncam):
            b, w = (B[c, i], W[c, i]) if phase == 0 else (W[c, i], B[c, i])
            x = vs[c, i]
            if np.isfinite(x) and np.isfinite(b) and np.isfinite(w) and w - b >= min_contrast:
                num += w - x
                den += w - b
        out[i] = num / den if den > 0 else np.nan
    return phase


def cell_darkness(samples: Array, n_cells: int, dark_ref: NDArray[np.int_], white_ref: NDArray[np.int_],
                  min_contrast: float) -> tuple[Array, int]:
    """Darkness of each cell from the grey levels (cameras, n_cells + references) of
    ``sample_sleeve``: (W - v) / (W - B) against the mean of its dark and white references
    (reference indices (n_cells, 3) each: the mean of the first two where both are sampled, else
    the third), weighted by contrast over the cameras; NaN where no
    camera has references of at least ``min_contrast``. And the checker's phase: 0 when the
    'dark' references are the darker ones (as the model says), 1 when they are the lighter ones
    (then swapped). Where more than 10% of them disagree, the phase is taken from each column's
    two patches alone (:func:`column_phase`), else -1 (then all NaN)."""
    out = np.empty(n_cells)
    phase = int(_darkness(samples, int(n_cells), dark_ref, white_ref, float(min_contrast), out, -1))
    if phase < 0:
        phase = column_phase(samples[:, n_cells:], min_contrast)
        if phase >= 0:
            _darkness(samples, int(n_cells), dark_ref, white_ref, float(min_contrast), out, phase)
    return out, phase


def column_phase(patches: Array, min_contrast: float, min_votes: int = 3) -> int:
    """The checker's phase from each column's own two patches (cameras, 2 n: the upper row's n
    patches, then the lower row's) [grey levels]: 0 where the upper patch of every even column is
    the darker one (and of every odd column the lighter), 1 the other way round; -1 unless at
    least ``min_votes`` (camera, column) pairs differ by ``min_contrast`` and all of them agree.

    The cells' references are their neighbouring columns' patches, and on a glossy cylinder under
    a coaxial light the column facing the camera carries a highlight that can lift its black patch
    above its neighbours' whites without clipping (path-traced 1414/47: 143 against 85-92): the
    references then disagree. A column's two patches lie at the same angle on the sleeve, so the
    highlight and the shading lift both alike and their order holds."""
    p = np.asarray(patches, float)
    n = p.shape[1] // 2
    with np.errstate(invalid="ignore"):
        diff = p[:, n:] - p[:, :n]  # lower - upper: > 0 where the upper patch is the darker
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)  # phase 0: even columns' upper patch dark
    vote = (diff * sign)[np.isfinite(diff) & (np.abs(diff) >= min_contrast)]
    if vote.size < min_votes or not (np.all(vote > 0) or np.all(vote < 0)):
        return -1
    return 0 if vote[0] > 0 else 1


@numba.njit(cache=True, nogil=True)
def _sample_cam(img: Any, P: Any, K: Any, dist: Any, out: Any) -> None:  # pragma: no cover
    for i in range(P.shape[0]):
        out[i] = _pixel(img, P[i, 0], P[i, 1], P[i, 2], K, dist)


def sample_camera_points(img: NDArray[np.uint8], points_cam: Array, K: Array, dist: Array) -> Array:
    """Grey levels (n,) at camera-frame points (n, 3) [m] projected with K and distortion
    [k1, k2, p1, p2, k3] (bilinear, BGR as luminance); NaN behind the camera or out of the image."""
    P = np.ascontiguousarray(points_cam, np.float64).reshape(-1, 3)
    out = np.empty(P.shape[0])
    _sample_cam(img, P, np.asarray(K, np.float64), np.asarray(dist, np.float64).reshape(5), out)
    return out
