"""The HTM corner fit's bias where the sleeve turns away from the camera: :func:`corner_patch`,
:func:`htm_bias`.

Towards the sleeve's silhouette its print is foreshortened (the column beyond a corner is
narrower in the image than the one before it) and, under a light beside the lens, dimmer (the
radiance of a matte print falls with the cosine between its normal and the line of sight).
Blurred, such a corner is not the HTM model's (two straight edges, one contrast, a linear
shading: cvs.corners.subpixel.htm_refine), and the fit lands on the brighter, wider side. Over
the 2420 used corners of 300 path-traced pairs, the error along the image direction of the
sleeve's circumference, towards the silhouette, averages -0.18 px where the corner faces the
camera at a cosine of 0.3-0.4, -0.12 px at 0.4-0.5, -0.08 px at 0.5-0.6 and under 0.05 px above
0.6; the fast renderer's corners show the same (-0.11, -0.06, -0.05 px) at its smaller blur
(docs/notes/foreshortened-corners.md).

:func:`htm_bias` predicts that bias corner by corner at a fitted pose: :func:`corner_patch` draws
the corner's window as the camera sees the sleeve there (rays through each pixel's sub-samples,
the calibrated distortion removed, meet the cylinder; the checker's columns at multiples of
the marker's beta, shaded by that cosine; no hit is the dark background; a Gaussian blur), the
same HTM fit runs on it from the corner's true place, and where it lands is the bias. The
tracker subtracts it and solves again (MarkerTracker._foreshortening_debiased).
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera
from wristmark.cvs.corners.subpixel import htm_radius, htm_refine, htm_weight_sigma
from wristmark.cvs.tracking.corner_refit import corner_edge_angles

Array = NDArray[np.float64]

__all__ = ["corner_patch", "htm_bias", "run_kernels_once"]

_DARK = 0.05  # the print's dark albedo over its white (the HTM fit is blind to the scale)
_LEVEL = 200.0  # grey level of a white square facing the camera in the drawn patch
_SMOOTH = 1e-3  # _draw: a pixel whose centre is within this of its corners' mean (over a facing white) is smooth


@numba.njit(cache=True, nogil=True, inline="always")
def _sample(q0: Any, J: Any, R: Any, o: Any, radius: float, beta: float, du: float,
            dv: float) -> tuple[int, float]:  # pragma: no cover (jit)
    """The drawing at the point (du, dv) [px] from the patch's origin: which square of the print
    it shows (0 none: off the sleeve or on its far side; else 1 + 2 column + 1 above z = 0) and
    its radiance over a facing white square's (the print's albedo times the cosine between the
    sleeve's normal and the ray)."""
    xn = q0[0] + J[0, 0] * du + J[0, 1] * dv
    yn = q0[1] + J[1, 0] * du + J[1, 1] * dv
    # the ray (xn, yn, 1) in {wm}: R^T v
    dx = R[0, 0] * xn + R[1, 0] * yn + R[2, 0]
    dy = R[0, 1] * xn + R[1, 1] * yn + R[2, 1]
    dz = R[0, 2] * xn + R[1, 2] * yn + R[2, 2]
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    dx, dy, dz = dx / norm, dy / norm, dz / norm
    a2 = dx * dx + dy * dy
    b2 = 2.0 * (o[0] * dx + o[1] * dy)
    c2 = o[0] * o[0] + o[1] * o[1] - radius * radius
    disc = b2 * b2 - 4.0 * a2 * c2
    if disc <= 0.0 or a2 <= 0.0:
        return 0, 0.0
    t = (-b2 - math.sqrt(disc)) / (2.0 * a2)  # the nearer hit
    if t <= 0.0:
        return 0, 0.0
    px, py, pz = o[0] + t * dx, o[1] + t * dy, o[2] + t * dz
    facing = -(px * dx + py * dy) / radius
    if facing <= 0.0:
        return 0, 0.0
    column = int(math.floor((math.atan2(py, px) % (2.0 * math.pi)) / beta))
    upper = pz > 0.0
    square = 1 + 2 * column + (1 if upper else 0)  # which square: a thin column between two samples changes it
    if (column % 2 == 0) == upper:
        return square, _DARK * min(facing, 1.0)
    return square, min(facing, 1.0)


@numba.njit(cache=True, nogil=True)
def _draw(q0: Any, J: Any, R: Any, o: Any, radius: float, beta: float, x0: float, y0: float, n: int, ss: int,
          adaptive: bool, out: Any) -> None:  # pragma: no cover (jit)
    """corner_patch's pixels: pixel (i, j) of ``out`` (n, n) is the mean over ss^2 sub-samples (a
    sheared grid) of the cosine-shaded checker where its ray meets the cylinder (0 off it). With
    ``adaptive``, a pixel whose four corners and centre show the same square of the print (no
    edge, corner or silhouette crosses it) and whose centre's radiance is within ``_SMOOTH`` of
    its corners' mean takes (corners' mean + 2 centre) / 3 instead (exact for a quadratic
    shading): 5 rays a pixel, shared corners, against ss^2 (over 631 corners at random poses the
    drawing's HTM bias moved by 0.003 px at most, 0.0002 px at the 99th percentile;
    tests/cvs/tracking/test_foreshortening.py)."""
    what = np.empty((n + 1, n + 1), np.int64)
    level = np.empty((n + 1, n + 1))
    for i in range(n + 1):
        for j in range(n + 1):
            what[i, j], level[i, j] = _sample(q0, J, R, o, radius, beta, j - 0.5 + x0, i - 0.5 + y0)
    for i in range(n):
        for j in range(n):
            w = what[i, j]
            if adaptive and w == what[i, j + 1] and w == what[i + 1, j] and w == what[i + 1, j + 1]:
                corners = 0.25 * (level[i, j] + level[i, j + 1] + level[i + 1, j] + level[i + 1, j + 1])
                centre_what, centre = _sample(q0, J, R, o, radius, beta, j + x0, i + y0)
                if centre_what == w and abs(centre - corners) <= _SMOOTH:
                    out[i, j] = _LEVEL * (corners + 2.0 * centre) / 3.0  # exact for a quadratic shading
                    continue
            acc = 0.0
            for a in range(ss):
                for b in range(ss):
                    # a sheared grid: ss^2 distinct offsets along each axis (an edge's place is
                    # kept to 1 / ss^2 px, not 1 / ss)
                    du = j + (b + (a + 0.5) / ss) / ss - 0.5 + x0
                    dv = i + (a + (b + 0.5) / ss) / ss - 0.5 + y0
                    acc += _sample(q0, J, R, o, radius, beta, du, dv)[1]
            out[i, j] = _LEVEL * acc / (ss * ss)


def corner_patch(camera: Camera, T_cam_marker: Array, radius: float, beta: float, centre_px: Array,
                 half_px: int = 7, supersample: int = 4, blur_px: float = 1.0,
                 adaptive: bool = True) -> tuple[NDArray[np.float32], Array]:
    """A (2 ``half_px`` + 1)^2 window of pixels whose middle one is centred on ``centre_px`` (2,)
    [raw px] (the grid follows the point, so that a point drawn there always has the same
    sub-pixel phase), drawn as ``camera`` sees a checker sleeve of ``radius`` [m] about z_wm at
    the pose ``T_cam_marker`` (4x4, {wm} in this camera's frame [m]): columns ``beta`` [rad] wide
    from x_wm, the dark squares where the column index is even above z = 0 and odd below, each
    sub-sample's radiance the cosine between the sleeve's normal and its ray (0 off the sleeve),
    ``supersample``^2 sub-samples a pixel (a sheared grid; with ``adaptive``, only where an edge,
    the corner or the silhouette crosses it or the shading bends: _draw), then a Gaussian blur of
    ``blur_px`` [px] (0: none). Returns the patch (float32 grey levels, a facing white square 200) and the
    raw-pixel place (2,) of its first pixel's centre."""
    c0 = np.asarray(centre_px, float).reshape(2)
    # the distortion removed at the centre and, to first order, around it (at most 0.03 px off
    # 7 px out, in the calibrated camera's corners)
    q = camera.undistort(np.vstack([c0, c0 + [1.0, 0.0], c0 + [0.0, 1.0]]))
    J = np.column_stack([q[1] - q[0], q[2] - q[0]])  # d(normalized) / d(px)
    T = np.asarray(T_cam_marker, float)
    R = np.ascontiguousarray(T[:3, :3])
    o = -R.T @ T[:3, 3]  # the camera centre in {wm}
    n = 2 * half_px + 1
    patch = np.zeros((n, n))
    _draw(q[0], J, R, o, float(radius), float(beta), float(-half_px), float(-half_px), n, int(supersample),
          bool(adaptive), patch)
    if blur_px > 0:
        B = _blur_matrix(n, float(blur_px))
        patch = B @ patch @ B.T
    return np.asarray(patch, np.float32), c0 - half_px


@functools.lru_cache(maxsize=32)
def _blur_matrix(n: int, sigma: float) -> Array:
    """The (n, n) matrix of a 1-D Gaussian blur of ``sigma`` [px], its kernel cut at 3 sigma, with
    the border replicated: B @ patch @ B.T blurs a patch (within 0.04 grey levels of 200 of
    cv2.GaussianBlur with BORDER_REPLICATE at 0.6-1.5 px). OpenCV's call on so small a patch
    cost 0.14 ms on average (its thread pool's overhead), two 15 x 15 matrix products a few us."""
    r = max(int(math.ceil(3.0 * sigma)), 1)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    B = np.zeros((n, n))
    for i in range(n):
        for t, w in zip(range(-r, r + 1), k):
            B[i, min(max(i + t, 0), n - 1)] += w
    return B


def run_kernels_once() -> None:
    """Load (or, first time, compile) this module's numba kernel (cvs.tracking.warmup)."""
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.05]
    camera = Camera(np.array([[1000.0, 0.0, 8.0], [0.0, 1000.0, 8.0], [0.0, 0.0, 1.0]]), np.zeros(5))
    corner_patch(camera, T, 0.003, math.pi / 6.0, np.array([8.0, 8.0]), 3, 2, 0.0)


def htm_bias(camera: Camera, T_cam_marker: Array, points_marker: Array, spacing_px: Array, radius: float,
             beta: float, facing: Array, max_facing: float = 0.7, blur_px: float = 1.0,
             refine_radius: int = 4, adaptive: bool = True, window_sigmas: float = 0.0) -> Array:
    """Where the HTM fit lands [px] (N, 2), relative to the true place, at each corner
    ``points_marker`` (N, 3) in {wm} [m] of a checker sleeve (``radius`` [m], columns ``beta``
    [rad]) seen by ``camera`` at the pose ``T_cam_marker`` (4x4, {wm} in its frame), each
    ``spacing_px`` (N,) [px] from its nearest neighbour (the fit's Gaussian weights) and facing
    the camera at the cosine ``facing`` (N,): :func:`corner_patch` fitted by
    cvs.corners.subpixel.htm_refine ((2 ``refine_radius`` + 1)^2 window, or ``window_sigmas``
    times its weights' sigma where larger, as the detector's) from the true corner
    and the print's edge angles there (``adaptive``: corner_patch's). Zero where ``facing`` is
    above ``max_facing`` or not positive, or where the fit fails."""
    P = np.asarray(points_marker, float).reshape(-1, 3)
    bias = np.zeros((P.shape[0], 2))
    f = np.asarray(facing, float)
    sel = np.flatnonzero((f > 0) & (f <= max_facing))
    if not sel.size:
        return bias
    T = np.asarray(T_cam_marker, float)
    true = camera.project(P[sel] @ T[:3, :3].T + T[:3, 3])
    edges = corner_edge_angles(T, P[sel], camera.project)
    for i, k in enumerate(sel):
        sw = float(htm_weight_sigma(float(spacing_px[k])))
        r = int(htm_radius(sw, refine_radius, window_sigmas)[0])
        half = r + 3
        patch, _ = corner_patch(camera, T, radius, beta, true[i], half, blur_px=blur_px, adaptive=adaptive)
        fit, _, ok = htm_refine(patch, np.array([[half, half]], float), edges[i:i + 1], r, sw)
        if ok[0]:
            bias[k] = fit[0] - half
    return bias
