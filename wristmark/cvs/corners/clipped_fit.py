"""X-corners between clipped white squares: the HTM grey-level model fitted with the clipping.

A sleeve close to the lens under the endoscope's light can expose its white squares at several
times full scale. Blurred (defocus, the lens), that white spreads over the corners and clips:
the dark squares no longer touch and no corner passes the X-corner test. The HTM fit
(cvs.corners.subpixel.htm_refine), whose model never clips, does not find such a corner either:
drawn with both whites at 4.7 times full scale and 1.5-3.5 px of blur, started 1 px off, it
ends 0.47-1.41 px off.
:func:`clipped_htm_refine` fits the same model, b + a tanh(u_a/s) tanh(u_b/s) + g.(p - c), with a
white level b + |a| that may lie far above full scale, and treats each pixel at ``clip_level`` or
more as censored: such a pixel only says that the model is at least ``clip_level`` there. The
dark squares' eroded tips, which the clipping leaves, then fix the corner: to 0.01 px where both
white squares are as bright. Where they differ (shading, the stripe), they erode the dark squares
differently, and the clipping hides by how much: 0.3-0.8 px off with whites at 3.5 and 5.5 times
full scale, 0.3-0.5 px on path-traced pairs. A model with each white square its own level leaves
the position undetermined (0.1-0.5 px off even where they are equal). The tracker therefore
counts such corners at 1 px of noise (MarkerTracker._retry_eroded).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

Array = NDArray[np.float64]

__all__ = ["clipped_htm_refine"]


def _fit_one(grey: Array, x0: int, y0: int, c: Array, edges: Array, clip_level: float,
             weight_sigma: float) -> tuple[Array, float] | None:
    """The censored fit in the window whose top-left pixel is (x0, y0): (centre, cost), or None."""
    h, w = grey.shape
    yy, xx = np.mgrid[0:h, 0:w]
    X, Y, Z = xx.ravel() + float(x0), yy.ravel() + float(y0), grey.ravel()
    sw = np.exp(-((X - c[0]) ** 2 + (Y - c[1]) ** 2) / (4.0 * weight_sigma ** 2))  # sqrt of Gaussian weights
    clipped = Z >= clip_level
    if clipped.all() or not clipped.any():
        return None

    def residuals(p: Array) -> Array:
        cx, cy, ea, eb, s, a, b, gx, gy = p
        dx, dy = X - cx, Y - cy
        ta = np.tanh((-np.sin(ea) * dx + np.cos(ea) * dy) / s)
        tb = np.tanh((-np.sin(eb) * dx + np.cos(eb) * dy) / s)
        m = b + a * ta * tb + gx * dx + gy * dy
        return sw * np.where(clipped, np.minimum(0.0, m - clip_level), m - Z)

    best: tuple[Array, float] | None = None
    for sign in (1.0, -1.0):  # which pair of opposite quadrants is white
        p0 = np.array([c[0], c[1], edges[0], edges[1], 2.0, sign * clip_level, clip_level, 0.0, 0.0])
        try:
            sol = least_squares(residuals, p0, method="lm", max_nfev=400)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if np.all(np.isfinite(sol.x)) and abs(sol.x[4]) > 1e-3 and (best is None or sol.cost < best[1]):
            best = (np.asarray(sol.x[:2], float), float(sol.cost))
    return best


def clipped_htm_refine(img: NDArray[np.uint8], pts: Array, edges: Array, spacing: Array | float,
                       clip_level: float = 250.0, radius_factor: float = 0.3, max_radius: int = 14,
                       max_move: float = 3.0) -> tuple[Array, NDArray[np.bool_]]:
    """Corners ``pts`` (N, 2) [px] of the grey image ``img`` fitted by the HTM model with its
    clipped pixels censored (a pixel at ``clip_level`` or more only bounds the model from below),
    started at ``pts`` and the edge angles ``edges`` (N, 2) [rad]. The window is (2 R + 1)^2
    pixels, R = ``radius_factor`` x ``spacing`` (per corner or one value [px]; the distance to the
    neighbouring corners) in [5, ``max_radius``] px, with Gaussian weights of sigma 0.6 R.
    Returns the points (N, 2) [px] and ok (N,): False (input returned) where the window leaves
    the image, holds no clipped or only clipped pixels, the fit fails, or it moves more than
    ``max_move`` px."""
    pts = np.asarray(pts, float).reshape(-1, 2)
    edges = np.asarray(edges, float).reshape(-1, 2)
    n = pts.shape[0]
    sp = np.broadcast_to(np.asarray(spacing, float), (n,))
    out, ok = pts.copy(), np.zeros(n, bool)
    H, W = img.shape[:2]
    for k in range(n):
        R = int(np.clip(radius_factor * sp[k], 5, max_radius)) if np.isfinite(sp[k]) else 5
        x0, y0 = int(round(pts[k, 0])) - R, int(round(pts[k, 1])) - R
        if x0 < 0 or y0 < 0 or x0 + 2 * R + 1 > W or y0 + 2 * R + 1 > H:
            continue
        patch = np.asarray(img[y0:y0 + 2 * R + 1, x0:x0 + 2 * R + 1], float)
        fit = _fit_one(patch, x0, y0, pts[k], edges[k], float(clip_level), 0.6 * R)
        if fit is not None and float(np.hypot(*(fit[0] - pts[k]))) <= max_move:
            out[k], ok[k] = fit[0], True
    return out, ok
