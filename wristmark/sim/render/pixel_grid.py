"""The renderer's pixel grid in normalized image coordinates: every raw pixel of a camera
undistorted, as :class:`sim.render.arm.RayMap` needs it.

:func:`undistorted_grid` runs OpenCV's own iteration of ``cv2.undistortPoints`` (the
fixed-point inversion of [k1, k2, p1, p2, k3] and its reprojection-error stop, skew ignored as
OpenCV ignores it) with the criteria of :meth:`cvs.camera.Camera.undistort`, as one numba kernel
over the grid: the same numbers bit for bit (tests/sim/render/test_pixel_grid.py) in 0.36-0.40
of the time, without building the grid's pixel list (``python bench/ray_map.py``, 2026-12-04:
1080p 0.77 s against 1.91 s, medians of 5 at a load of ~9). A renderer
pays it once per camera and process (:func:`sim.render.arm.ray_map`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera

F64 = NDArray[np.float64]
MAX_ITERATIONS = 40  # Camera.undistort's criteria: 40 iterations or a reprojection error under EPS [px]
EPS = 1e-12


@numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")
def _undistort_rows(u0: float, v0: float, w: int, h: int, fx: float, fy: float, cx: float, cy: float, k1: float,
                    k2: float, p1: float, p2: float, k3: float, max_count: int, eps: float) -> F64:
    out = np.empty((h, w, 2))
    ifx, ify = 1.0 / fx, 1.0 / fy
    for r in range(h):
        v = v0 + r
        for c in range(w):
            u = u0 + c
            x = (u - cx) * ifx
            y = (v - cy) * ify
            x0, y0 = x, y
            error = np.inf
            j = 0
            while j < max_count and not error < eps:  # OpenCV's order of the two stops
                r2 = x * x + y * y
                icdist = 1.0 / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2)
                if icdist < 0:  # OpenCV: give up on a point the model folds over
                    x = (u - cx) * ifx
                    y = (v - cy) * ify
                    break
                delta_x = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
                delta_y = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
                x = (x0 - delta_x) * icdist
                y = (y0 - delta_y) * icdist
                r2 = x * x + y * y
                r4 = r2 * r2
                cdist = 1 + k1 * r2 + k2 * r4 + k3 * (r4 * r2)
                xd = x * cdist + p1 * (2 * x * y) + p2 * (r2 + 2 * x * x)
                yd = y * cdist + p1 * (r2 + 2 * y * y) + p2 * (2 * x * y)
                error = math.sqrt((xd * fx + cx - u) ** 2 + (yd * fy + cy - v) ** 2)
                j += 1
            out[r, c, 0] = x
            out[r, c, 1] = y
    return out


def undistorted_grid(camera: Camera, u0: float, v0: float, w: int, h: int) -> F64:
    """Normalized image coordinates (x/z, y/z) (h, w, 2) of the raw pixels (u0 + i, v0 + j),
    i < w, j < h [px], distortion removed exactly as ``camera.undistort`` removes it."""
    K = np.asarray(camera.K, np.float64)
    d = np.zeros(5)
    dist = np.asarray(camera.dist, np.float64).ravel()
    d[: min(5, dist.size)] = dist[:5]
    k1, k2, p1, p2, k3 = (float(x) for x in d)
    grid: F64 = _undistort_rows(float(u0), float(v0), int(w), int(h), float(K[0, 0]), float(K[1, 1]), float(K[0, 2]),
                                float(K[1, 2]), k1, k2, p1, p2, k3, MAX_ITERATIONS, EPS)
    return grid
