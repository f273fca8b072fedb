"""Another detector's corners fitted again by the paper detector's grey-level model:
:func:`corner_edge_angles`, :func:`nearest_spacing`, :func:`refit_corners`, :func:`refit_corners_clipped`.

The saddle detector ('auto''s second try, cvs.corners.saddle) finds chains where the paper
detector's X-corner test misses a corner (a highlight stripe bending its edge along the chain by
25 deg, clipping), but its corners are coarser: 0.17 px RMS on the matte bench against the HTM
fit's 0.06 (docs/results.md). Given a pose fitted to them, each matched corner is fitted again
by the HTM model (cvs.corners.subpixel.htm_refine) in the detector's window, started at its
position and at the pose's own edge directions (the print's lines around and along the sleeve
through it, projected): the paper detector's accuracy on the saddle detector's chain.

A corner seen in one view only is looked for in the other at the place a pose puts it
(:func:`partner_corners`: the plain fit, or the censored one where its window clips).

Corners found on a reduced or an eroded image (corners blurred over several pixels, or white
squares clipped and blurred over them: MarkerTracker._retry_reduced and _retry_eroded, the
tracker's last tries) are fitted again on the image itself by the
same model with its clipped pixels censored (:func:`refit_corners_clipped`,
cvs.corners.clipped_fit).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.corners.clipped_fit import clipped_htm_refine
from wristmark.cvs.corners.subpixel import (
    HTM_WEIGHT_MAX_PX,
    HTM_WEIGHT_PER_SPACING,
    htm_radius,
    htm_refine,
    htm_weight_sigma,
)
from wristmark.cvs.corners.xcorner_test import htm_correlation
from wristmark.cvs.gray_image import gray_crop

Array = NDArray[np.float64]

__all__ = ["corner_edge_angles", "nearest_spacing", "partner_corners", "refit_corners", "refit_corners_clipped"]


def corner_edge_angles(T_cam_marker: Array, points_marker: Array, project: Callable[[Array], Array]) -> Array:
    """The image angles [rad] (N, 2) of the print's two lines through each corner, around the
    sleeve and along it, at the pose ``T_cam_marker`` (4x4, {wm} in the camera's frame) of the
    corners ``points_marker`` (N, 3) in {wm} [m]; ``project`` maps (M, 3) camera-frame points
    [m] to raw pixels (M, 2)."""
    P = np.asarray(points_marker, float).reshape(-1, 3)
    T = np.asarray(T_cam_marker, float)
    R, t = T[:3, :3], T[:3, 3]
    a = np.arctan2(P[:, 1], P[:, 0])
    around = np.column_stack([-np.sin(a), np.cos(a), np.zeros_like(a)])
    along = np.tile([0.0, 0.0, 1.0], (P.shape[0], 1))
    h = 1e-4  # [m]: a tenth of a millimetre, well inside one patch
    C = P @ R.T + t
    uv = np.asarray(project(np.vstack([C, C + h * around @ R.T, C + h * along @ R.T])), float).reshape(3, -1, 2)
    d = uv[1:] - uv[0][None]
    return np.column_stack([np.arctan2(d[0, :, 1], d[0, :, 0]), np.arctan2(d[1, :, 1], d[1, :, 0])])


def nearest_spacing(uv: Array) -> Array:
    """Each of the points ``uv`` (N, 2) [px]: its distance [px] to the nearest other one (inf
    alone; empty for none)."""
    pts = np.asarray(uv, float).reshape(-1, 2)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2) + np.diag(np.full(pts.shape[0], np.inf))
    return np.asarray(d.min(axis=1), float) if pts.shape[0] else np.zeros(0)


def refit_corners(view: NDArray[np.uint8], uv: Array, edges: Array, radius: int = 4,
                  max_sigma_px: float = HTM_WEIGHT_MAX_PX, window_sigmas: float = 0.0) -> Array:
    """The corners ``uv`` (N, 2) [raw px] of ``view`` (grey or BGR) fitted again by the HTM model
    (cvs.corners.subpixel.htm_refine: (2 radius + 1)^2 window, or ``window_sigmas`` times the
    weights' sigma where larger, Gaussian weights 0.12 times the distance to the nearest other
    corner, in [1.5, ``max_sigma_px``] px; the paper detector's own fit with its
    ``refine_radius`` and ``refine_window_sigmas``, by default 4 and 1.5), started at ``uv`` and
    ``edges`` (N, 2) [rad]; a corner whose fit fails, moves more than 1.5 px or whose window
    leaves the image keeps its position."""
    pts = np.asarray(uv, float).reshape(-1, 2)
    out = pts.copy()
    n = pts.shape[0]
    if n == 0:
        return out
    h, w = view.shape[:2]
    spacing = nearest_spacing(pts) if n > 1 else np.full(1, HTM_WEIGHT_MAX_PX / HTM_WEIGHT_PER_SPACING)
    pad = int(htm_radius(htm_weight_sigma(spacing, max_sigma_px), radius, window_sigmas).max()) + 2
    inside = (pts[:, 0] >= pad) & (pts[:, 0] < w - pad) & (pts[:, 1] >= pad) & (pts[:, 1] < h - pad)
    if not inside.any():
        return out
    x0, y0 = int(np.floor(pts[inside, 0].min())) - pad, int(np.floor(pts[inside, 1].min())) - pad
    x1, y1 = int(np.ceil(pts[inside, 0].max())) + pad + 1, int(np.ceil(pts[inside, 1].max())) + pad + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    grey = gray_crop(view, (x0, y0, x1, y1))
    ref, _, ok = htm_refine(grey, pts[inside] - [x0, y0], np.asarray(edges, float).reshape(-1, 2)[inside], radius,
                            htm_weight_sigma(spacing[inside], max_sigma_px), window_sigmas=window_sigmas)
    moved = out[inside]
    moved[ok] = ref[ok] + [x0, y0]
    out[inside] = moved
    return out


def refit_corners_clipped(view: NDArray[np.uint8], uv: Array, edges: Array,
                          clip_level: float = 250.0) -> tuple[Array, NDArray[np.bool_]]:
    """The corners ``uv`` (N, 2) [raw px] of the grey image ``view`` fitted again by the HTM model
    with its clipped pixels (``clip_level`` or more) censored (cvs.corners.clipped_fit: window 0.3
    times the distance to the nearest other corner, 5-14 px), started at ``uv`` and ``edges``
    (N, 2) [rad]. Returns the fitted corners (N, 2) and ok (N,): False where a corner's fit failed
    (its input position returned)."""
    pts = np.asarray(uv, float).reshape(-1, 2)
    n = pts.shape[0]
    if n == 0:
        return pts.copy(), np.zeros(0, bool)
    spacing = nearest_spacing(pts) if n > 1 else np.full(1, np.inf)
    return clipped_htm_refine(view, pts, edges, spacing, clip_level)


def partner_corners(view: NDArray[np.uint8], uv: Array, edges: Array, spacing: Array | float,
                    clip_level: float = 250.0, radius: int = 4, cc_min: float = 0.8,
                    cc_radius: int = 4, window_sigmas: float = 0.0) -> tuple[Array, NDArray[np.bool_]]:
    """Corners of the grey image ``view`` fitted by the HTM model from predicted places ``uv``
    (N, 2) [raw px] and edge angles ``edges`` (N, 2) [rad], each ``spacing`` [px] from its
    nearest neighbouring corner (per corner or one value): the paper detector's fit ((2
    ``radius`` + 1)^2 window, or ``window_sigmas`` times the weights' sigma where larger, Gaussian
    weights 0.12 ``spacing`` in [1.5, 4] px) where no pixel of
    that window reaches ``clip_level``, else the fit with the clipped pixels censored
    (:func:`refit_corners_clipped`'s). Returns the fitted corners (N, 2) and ok (N,): False (input
    returned) where the fit fails, moves more than 1.5 px or its window leaves the image, or
    (the plain fit) where the grey levels of the (2 ``cc_radius`` + 1)^2 window there correlate
    with the HTM at the given edges by less than ``cc_min`` (the paper's X-corner test, eq. 8:
    a flat or edge-only patch is no corner)."""
    pts = np.asarray(uv, float).reshape(-1, 2)
    e = np.asarray(edges, float).reshape(-1, 2)
    gaps = np.broadcast_to(np.asarray(spacing, float), (pts.shape[0],))
    out, ok = pts.copy(), np.zeros(pts.shape[0], bool)
    h, w = view.shape[:2]
    for k, (x, y) in enumerate(pts):
        sw = float(htm_weight_sigma(gaps[k]))
        r = int(htm_radius(sw, radius, window_sigmas)[0])
        pad = int(np.ceil(max(r, 0.3 * gaps[k]))) + 2
        if not (pad <= x < w - pad and pad <= y < h - pad):
            continue
        x0, y0 = int(round(x)) - r, int(round(y)) - r
        grey = gray_crop(view, (x0, y0, x0 + 2 * r + 1, y0 + 2 * r + 1))
        if grey.max() >= clip_level:
            fit, good = clipped_htm_refine(view, pts[k:k + 1], e[k:k + 1], gaps[k], clip_level, max_move=1.5)
        else:
            fit, _, good = htm_refine(grey, pts[k:k + 1] - [x0, y0], e[k:k + 1], r, sw)
            fit = fit + [x0, y0]
            cx, cy = int(round(fit[0, 0])), int(round(fit[0, 1]))
            good &= (cc_radius <= cx < w - cc_radius and cc_radius <= cy < h - cc_radius
                     and abs(htm_correlation(view, cx, cy, cc_radius, e[k, 0], e[k, 1], 1.0)) >= cc_min)
        if good[0]:
            out[k], ok[k] = fit[0], True
    return out, ok
