"""How well a stereo fit's corners determine the tip: its standard deviation from the fit's
reprojection Jacobian at a given corner noise (first order).

A fit on three corners of one ring per view (a small or steeply seen sleeve) reprojects to a few
hundredths of a pixel and can still put the tip 2-9 mm off: the ring's tilt is barely seen, and
the tip lies ``tip_offset`` beyond the ring. Its tip sigma is then 2-9 mm at 0.3 px of corner
noise, where well seen sleeves give 0.1-0.3 mm (docs/notes/steep-views.md).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.tracking.window_max import bright_windows

Array = NDArray[np.float64]

__all__ = ["corner_contrast", "corner_sigmas", "near_clipped", "tip_sigma"]


def _skew(v: Array) -> Array:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _unit(i: int, h: float) -> Array:
    """h along axis i (the other two components 0)."""
    v = np.zeros(3)
    v[i] = h
    return v


# tip_sigma's finite-difference steps [rad], [m], and the perturbations they give (built once)
_H_ROT, _H_TR = 1e-6, 1e-7
_TURNS = tuple(np.eye(3) + _skew(_unit(i, _H_ROT)) for i in range(3))  # first order: exp([w]x) ~ I + [w]x
_SHIFTS = tuple(_unit(i, _H_TR) for i in range(3))
_STEPS = np.array([_H_ROT] * 3 + [_H_TR] * 3)
for _a in (*_TURNS, *_SHIFTS, _STEPS):
    _a.setflags(write=False)


def _exact_ranks(n: int, q: tuple[float, ...]) -> tuple[int, ...] | None:
    """The sorted positions on which numpy's (linear) percentiles ``q`` [%] of ``n`` values fall
    exactly, or None when one of them falls between two positions (then only np.percentile gives
    its bits). Probed with step values: the percentile is the i-th smallest of any values only
    when it is 0 where the values after position i are 1 and the rest 0, and 1 where the values
    from position i on are 1."""
    return _ranks(int(n), tuple(float(x) for x in q))


@lru_cache(maxsize=32)
def _ranks(n: int, q: tuple[float, ...]) -> tuple[int, ...] | None:
    out = []
    pos = np.arange(n)
    for x in q:
        i = int(np.floor(float(np.percentile(pos.astype(np.float64), x)) + 0.5))
        after, from_i = (pos > i).astype(np.float64), (pos >= i).astype(np.float64)
        if not (0 <= i < n and float(np.percentile(after, x)) == 0.0 and float(np.percentile(from_i, x)) == 1.0):
            return None
        out.append(i)
    return tuple(out)


def corner_contrast(view: NDArray[np.uint8], uv: Array, r: int = 4) -> Array:
    """Each corner's contrast [grey levels]: the spread (90th - 10th percentile) of the grey
    levels in the (2 r + 1)^2 window around it (the HTM fit's window, cvs.corners.subpixel);
    0 where the window leaves the image. Where both percentiles fall on a sorted position (r = 4
    or 5: :func:`_exact_ranks`) they are taken by one partition of the grey levels, to the bit
    np.percentile's, at a fraction of its cost."""
    from wristmark.cvs.gray_image import to_gray

    pts = np.rint(np.asarray(uv, float).reshape(-1, 2)).astype(int)
    h, w = view.shape[:2]
    out = np.zeros(pts.shape[0])
    inside = (pts[:, 0] >= r) & (pts[:, 0] < w - r) & (pts[:, 1] >= r) & (pts[:, 1] < h - r)
    if inside.any():  # every window at once: row k holds corner k's (2 r + 1)^2 pixels
        d = np.arange(-r, r + 1)
        ys = pts[inside, 1][:, None, None] + d[None, :, None]
        xs = pts[inside, 0][:, None, None] + d[None, None, :]
        windows = np.ascontiguousarray(view[ys, xs])  # (K, 2r+1, 2r+1[, channels])
        k, n = windows.shape[0], (2 * r + 1) ** 2
        grey = to_gray(windows.reshape(k, n, *windows.shape[3:]))
        ranks = _exact_ranks(n, (10.0, 90.0))
        if ranks is not None:  # uint8 order statistics: the same integers as the float percentiles
            part = np.partition(grey, ranks, axis=1)
            out[inside] = part[:, ranks[1]].astype(np.float64) - part[:, ranks[0]].astype(np.float64)
        else:
            lo, hi = np.percentile(grey.astype(np.float64), [10.0, 90.0], axis=1)
            out[inside] = hi - lo
    return out


def near_clipped(view: NDArray[np.uint8], uv: Array, radius_px: float, level: int) -> NDArray[np.bool_]:
    """Whether each corner (x, y) [px] has a pixel whose grey level is at or above ``level`` (a
    clipped highlight) in its square window: columns int(x - r) to int(x + r), rows likewise
    (r = ``radius_px``, at least 1 px; int() towards zero), clipped to the image. One kernel call
    rules out every window without a colour channel that bright (cvs.tracking.window_max); the
    rest are tested on their grey levels, one window at a time."""
    from wristmark.cvs.gray_image import to_gray

    bright, box = bright_windows(view, np.asarray(uv, float).reshape(-1, 2), max(float(radius_px), 1.0), level)
    out = np.zeros(bright.shape[0], bool)
    for k in np.flatnonzero(bright):
        u0, v0, u1, v1 = (int(b) for b in box[k])
        out[k] = int(to_gray(np.ascontiguousarray(view[v0:v1, u0:u1])).max()) >= level
    return out


def corner_sigmas(view: NDArray[np.uint8], uv: Array, floor_px: float, contrast_noise: float,
                  clipped_sigma_px: float = 0.0, clipped_level: int = 250, clipped_radius_px: float = 0.0) -> Array:
    """Each corner's position noise [px]: ``floor_px`` combined with ``contrast_noise`` [px x grey
    levels] over its contrast (corner_contrast): a corner's localisation noise grows as the image
    noise over its contrast (path-traced 1080p pairs, seed 101: 0.24 px RMS at 20-40 grey levels,
    0.18 at 40-80, 0.13 above; docs/notes/highlight-stripe.md); and with ``clipped_sigma_px``
    for a corner with a pixel at ``clipped_level`` or more within ``clipped_radius_px``
    (near_clipped): beside a highlight stripe the HTM fit's linear shading does not model the
    light, and such corners were 0.1-1.6 px off on the same pairs."""
    pts = np.asarray(uv, float).reshape(-1, 2)
    var = np.full(pts.shape[0], floor_px**2)
    if contrast_noise > 0:
        var = var + (contrast_noise / np.maximum(corner_contrast(view, pts), 1.0)) ** 2
    if clipped_sigma_px > 0 and clipped_radius_px > 0 and pts.shape[0]:
        var = var + np.where(near_clipped(view, pts, clipped_radius_px, clipped_level), clipped_sigma_px**2, 0.0)
    return np.asarray(np.sqrt(var), float)


def tip_sigma(camera: StereoCamera, T_left_marker: Array, points_left: Array, points_right: Array,
              tips_marker: Array, corner_sigma_px: float,
              sigmas_px: tuple[Array, Array] | None = None) -> float:
    """The largest 3D standard deviation [m] of the points ``tips_marker`` (K, 3) in {wm} [m]
    (e.g. the tip at either end of the sleeve) for the pose ``T_left_marker`` of {wm} in {ll}
    fitted to the corners ``points_left`` / ``points_right`` (N, 3) in {wm} [m] seen by each
    camera, each pixel coordinate with noise ``corner_sigma_px`` [px], or per corner
    ``sigmas_px`` (left (N_l,), right (N_r,)) [px]; inf when the corners do not determine the
    pose."""
    T = np.asarray(T_left_marker, float)
    R, t = T[:3, :3], T[:3, 3]
    Pl = np.asarray(points_left, float).reshape(-1, 3)
    Pr = np.asarray(points_right, float).reshape(-1, 3)

    # the pose and its six perturbations (R exp([w]x), t + v), projected in one call per camera
    poses = [(R, t), *((R @ turn, t) for turn in _TURNS), *((R, t + v) for v in _SHIFTS)]
    k = len(poses)
    views = [(camera.project_left, Pl), (camera.project_right, Pr)]
    uv = np.hstack([project(np.concatenate([P @ Rx.T + tx for Rx, tx in poses])).reshape(k, -1) if len(P)
                    else np.zeros((k, 0)) for project, P in views])
    if uv.shape[1] < 6:
        return float("inf")
    J = ((uv[1:] - uv[0]) / _STEPS[:, None]).T  # (2 N, 6)
    if sigmas_px is None:
        sig = np.full(J.shape[0], float(corner_sigma_px))
    else:  # per corner, both coordinates (u, v rows of each corner in turn)
        sig = np.repeat(np.concatenate([np.asarray(s, float).reshape(-1) for s in sigmas_px]), 2)
        if sig.size != J.shape[0]:
            raise ValueError("sigmas_px: one sigma per corner of points_left and points_right")
    J = J / sig[:, None]  # whitened: pose covariance (J' J)^-1
    JtJ = J.T @ J
    if not np.all(np.isfinite(JtJ)) or np.linalg.cond(JtJ) > 1e14:
        return float("inf")
    C = np.linalg.inv(JtJ)  # pose covariance: (rotation vector, translation)
    worst = 0.0
    for c in np.asarray(tips_marker, float).reshape(-1, 3):
        Jt = np.hstack([-R @ _skew(c), np.eye(3)])  # d tip / d (w, v) for R exp([w]x), t + v
        worst = max(worst, float(np.sqrt(max(np.trace(Jt @ C @ Jt.T), 0.0))))
    return worst
