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
    """The censored fit in the window whose top-left pixel is (x0, y0): (centre, cost), or None.
    Levenberg-Marquardt with the model's analytic Jacobian, started at the sign of the checker
    (which pair of opposite quadrants is white) that a linear fit of the unclipped pixels at the
    start gives; the other sign only where that fit fails."""
    h, w = grey.shape
    yy, xx = np.mgrid[0:h, 0:w]
    X, Y, Z = xx.ravel() + float(x0), yy.ravel() + float(y0), grey.ravel()
    sw = np.exp(-((X - c[0]) ** 2 + (Y - c[1]) ** 2) / (4.0 * weight_sigma ** 2))  # sqrt of Gaussian weights
    clipped = Z >= clip_level
    if clipped.all() or not clipped.any():
        return None

    def terms(p: Array) -> tuple[Array, ...]:
        cx, cy, ea, eb, s, a, b, gx, gy = p
        dx, dy = X - cx, Y - cy
        ua = -np.sin(ea) * dx + np.cos(ea) * dy
        ub = -np.sin(eb) * dx + np.cos(eb) * dy
        ta, tb = np.tanh(ua / s), np.tanh(ub / s)
        m = b + a * ta * tb + gx * dx + gy * dy
        return dx, dy, ua, ub, ta, tb, m

    def residuals(p: Array) -> Array:
        m = terms(p)[-1]
        return sw * np.where(clipped, np.minimum(0.0, m - clip_level), m - Z)

    def jacobian(p: Array) -> Array:
        _, _, ea, eb, s, a, _, gx, gy = p
        dx, dy, ua, ub, ta, tb, m = terms(p)
        da, db = a * (1.0 - ta * ta) * tb / s, a * ta * (1.0 - tb * tb) / s  # dm/du_a, dm/du_b
        J = np.column_stack([
            da * np.sin(ea) + db * np.sin(eb) - gx,  # d/dcx
            -da * np.cos(ea) - db * np.cos(eb) - gy,  # d/dcy
            da * (-np.cos(ea) * dx - np.sin(ea) * dy),  # d/dea
            db * (-np.cos(eb) * dx - np.sin(eb) * dy),  # d/deb
            -(da * ua + db * ub) / s,  # d/ds
            ta * tb, np.ones_like(ta), dx, dy,  # d/da, d/db, d/dgx, d/dgy
        ])
        live = ~clipped | (m < clip_level)  # a censored pixel above the level has no residual
        return (sw * live)[:, None] * J

    p_lin = np.array([c[0], c[1], edges[0], edges[1], 2.0, 0.0, 0.0, 0.0, 0.0])
    _, _, _, _, ta, tb, _ = terms(p_lin)
    A = np.column_stack([ta * tb, np.ones_like(ta), X - c[0], Y - c[1]])[~clipped] * sw[~clipped, None]
    first = 1.0 if float(np.linalg.lstsq(A, Z[~clipped] * sw[~clipped], rcond=None)[0][0]) >= 0 else -1.0
    for sign in (first, -first):
        p0 = np.array([c[0], c[1], edges[0], edges[1], 2.0, sign * clip_level, clip_level, 0.0, 0.0])
        try:
            sol = least_squares(residuals, p0, jac=jacobian, method="lm", max_nfev=400)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if np.all(np.isfinite(sol.x)) and abs(sol.x[4]) > 1e-3 and np.hypot(*(sol.x[:2] - c)) <= 3.0:
            return np.asarray(sol.x[:2], float), float(sol.cost)
    return None


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
