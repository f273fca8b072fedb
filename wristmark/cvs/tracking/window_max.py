"""Numba kernel for cvs.tracking.tip_uncertainty.near_clipped: the square windows around points,
and which of them hold a pixel with a colour channel at or above a level.

A pixel's grey level (cv2.cvtColor: a weighted mean of its B, G, R channels, weights summing to
one, rounded to the nearest) is at most its largest channel, so a window with no channel at the
level holds no grey level at it either: the kernel rules out those windows, one call for all
of them and without the interpreter lock (numpy's gather of the windows took 5-10 small
operations per call); near_clipped tests the few left on their grey levels as defined.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["bright_windows"]


@numba.njit(cache=True, nogil=True)
def _kernel(img: Any, pts: Any, rad: float, level: int, box: Any, out: Any) -> None:  # pragma: no cover
    h, w = img.shape[0], img.shape[1]
    channels = min(img.shape[2], 3)  # BGRA: alpha is no colour
    for k in range(pts.shape[0]):
        u0, u1 = max(int(pts[k, 0] - rad), 0), min(int(pts[k, 0] + rad) + 1, w)  # int(): towards zero
        v0, v1 = max(int(pts[k, 1] - rad), 0), min(int(pts[k, 1] + rad) + 1, h)
        box[k, 0], box[k, 1], box[k, 2], box[k, 3] = u0, v0, u1, v1
        hit = False
        for v in range(v0, v1):
            for u in range(u0, u1):
                for c in range(channels):
                    if img[v, u, c] >= level:
                        hit = True
                        break
                if hit:
                    break
            if hit:
                break
        out[k] = hit


def bright_windows(img: NDArray[np.uint8], uv: NDArray[np.float64], rad: float, level: int
                   ) -> tuple[NDArray[np.bool_], NDArray[np.intp]]:
    """Per point (x, y) [px] of ``uv`` (N, 2): its window, columns int(x - rad) to int(x + rad)
    and rows likewise (int() towards zero) clipped to the image, as (u0, v0, u1, v1) end
    exclusive (N, 4); and whether a pixel there of ``img`` (uint8 grey, BGR or BGRA) has a
    channel (B, G or R; the grey level itself) at or above ``level`` (False for an empty window)."""
    h, w = img.shape[:2]
    view = img.reshape(h, w, 1) if img.ndim == 2 else img
    pts = np.ascontiguousarray(uv, np.float64).reshape(-1, 2)
    box = np.zeros((pts.shape[0], 4), np.intp)
    out = np.zeros(pts.shape[0], np.bool_)
    if pts.shape[0]:
        _kernel(view, pts, float(rad), int(level), box, out)
    return out, box
