"""A coded sleeve's pose from two stereo corners and its print: the tracker's last try.

Seen 35 deg or more from square in a dim image, a coded sleeve can show only the two corners
that face the camera: the next ones fail the X-corner test, no chain of three forms, and the
pair is lost (path-traced 1414/15; docs/notes/highlight-stripe.md, "Two corners a view"). Two
stereo pairs fix a chord of the corner ring, but not the turn about it nor the roll:

1. :func:`stereo_chords`: chains of two of each view (cvs.corners.detector.chains_of_two)
   paired across the views, kept where both corners lie on one rectified row and their
   triangulated distance is the ring's chord (texture pairs rarely are);
2. :func:`axis_from_edges`: the print's line along the sleeve through each corner is seen in
   both views (the X-corner test's edge angles): the sleeve axis' direction is the turn about
   the chord that projects onto those lines (up to its sign);
3. :func:`roll_hypotheses`: every adjacent corner pair of the ring, both ways round, put on
   the chord near that turn and scored by the print's bar samples found there
   (cvs.tracking.print_edges), the code cells' included (their places need the roll); the best
   few refined with their bars. Rivals are the hypotheses that put the tip elsewhere (those that
   agree on it differ only in the roll they name, which the code decides).

MarkerTracker._retry_two_pairs keeps the best where it has the most samples, `two_pairs_margin` times the
code cells' samples of any rival, its code read names the same roll, and the tip's sigma from
the two corners and the bars together passes the tracker's gates.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.corners.xcorners import XCorners
from wristmark.cvs.tracking.print_edges import (
    Bars,
    Corners,
    PrintedEdges,
    bar_pairs,
    measure_edges,
    refine_with_edges,
)
from wristmark.cvs.tracking.result import Array
from wristmark.cvs.tracking.rigid_fit import chord_starts, roll_about_z
from wristmark.cvs.tracking.sleeve_facing import corner_facing
from wristmark.cvs.tracking.stereo_match import StereoRectifier
from wristmark.models.marker import MarkerModel

__all__ = ["RollFit", "StereoChord", "axis_from_edges", "roll_hypotheses", "stereo_chords"]

_TURNS = 72  # starts about the chord: 5 deg apart
_MIN_REFINE_BARS = 3  # bar samples a hypothesis needs to be refined (fewer leave the fit singular)


@dataclass(frozen=True)
class StereoChord:
    """Two corners seen in both views: ``uv_left``, ``uv_right`` (2, 2) raw pixels (row i of
    each is the same corner), ``points`` (2, 3) triangulated in {ll} [m], ``edges_left``,
    ``edges_right`` (2, 2) the X-corner test's two edge angles of each corner [rad], ``dy_px``
    (2,) rectified y right - left [px]."""

    uv_left: Array
    uv_right: Array
    points: Array
    edges_left: Array
    edges_right: Array
    dy_px: Array


def stereo_chords(rectifier: StereoRectifier, left: Sequence[XCorners], right: Sequence[XCorners],
                  chord_m: float, max_dy_px: float, chord_tol: float = 0.1) -> list[StereoChord]:
    """Each chain of two of the left view (``left``: XCorners of two corners) with each of the
    right view, both ways round, where both corners lie within ``max_dy_px`` of one rectified
    row, in front of both cameras, and ``chord_m`` [m] apart within the fraction ``chord_tol``."""
    out: list[StereoChord] = []
    P1, P2, R1 = rectifier.P1, rectifier.P2, rectifier.R1
    for xl in left:
        rl = rectifier.left(xl.corners)
        for xr in right:
            for order in ((0, 1), (1, 0)):
                ur, er = xr.corners[list(order)], xr.edges[list(order)]
                rr = rectifier.right(ur)
                dy = rr[:, 1] - rl[:, 1]
                if not np.all(np.abs(dy) <= max_dy_px):
                    continue
                Xh = cv2.triangulatePoints(P1, P2, rl.T.astype(float), rr.T.astype(float))
                if not np.all(np.abs(Xh[3]) > 1e-12):
                    continue
                X = (Xh[:3] / Xh[3]).T @ R1  # rectified left frame -> {ll}
                right_z = (X @ np.asarray(rectifier.camera.R, float).T)[:, 2] + float(
                    np.asarray(rectifier.camera.T, float).reshape(3)[2])
                if not (np.all(X[:, 2] > 0) and np.all(right_z > 0)):
                    continue
                d = float(np.linalg.norm(X[1] - X[0]))
                if abs(d / chord_m - 1.0) > chord_tol:
                    continue
                out.append(StereoChord(xl.corners.copy(), ur.copy(), X, xl.edges.copy(), er.copy(), dy))
    return out


def _angle_error(predicted: Array, observed: Array) -> Array:
    """|predicted - nearest of the two observed edge angles| modulo pi [rad]: (..., K) against (K, 2)."""
    d = np.abs((predicted[..., None] - observed + 0.5 * math.pi) % math.pi - 0.5 * math.pi)
    return np.asarray(d.min(axis=-1), float)


def axis_from_edges(camera: StereoCamera, chord: StereoChord, marker: MarkerModel,
                    max_rms_deg: float = 10.0) -> Array | None:
    """The sleeve axis' direction in {ll} (unit, its sign open) for which the print's lines
    along the sleeve through the chord's two corners project onto one of each corner's edges in
    both views: the turn about the chord (5 deg steps, then 1 deg about the best) with the least
    squared angle error; None where its RMS error exceeds ``max_rms_deg``."""
    P = np.asarray(marker.corners()[:2], float)  # any adjacent pair: the same chord

    def errors(starts: list[Array]) -> Array:
        R = np.stack([T[:3, :3] for T in starts])
        t = np.stack([T[:3, 3] for T in starts])
        C = np.einsum("nij,kj->nki", R, P) + t[:, None, :]  # (n, 2, 3) in {ll}
        A = C + 1e-4 * R[:, None, :, 2]  # 0.1 mm along the axis
        err = []
        for project, observed in ((camera.project_left, chord.edges_left), (camera.project_right, chord.edges_right)):
            uv = np.asarray(project(np.vstack([C.reshape(-1, 3), A.reshape(-1, 3)])), float).reshape(2, -1, 2, 2)
            d = uv[1] - uv[0]
            err.append(_angle_error(np.arctan2(d[..., 1], d[..., 0]), observed))
        return np.concatenate(err, axis=1)  # (n, 4)

    coarse = chord_starts(P, chord.points, _TURNS)
    e = errors(coarse)
    best = coarse[int(np.argmin((np.minimum(e, math.radians(20.0)) ** 2).sum(axis=1)))]
    fine = [best @ T for T in _about_chord(best, P, np.radians(np.arange(-5.0, 5.5, 1.0)))]
    e = errors(fine)
    k = int(np.argmin((e ** 2).sum(axis=1)))
    if math.degrees(math.sqrt(float(np.mean(e[k] ** 2)))) > max_rms_deg:
        return None
    return np.asarray(fine[k][:3, 2], float).copy()


def _about_chord(T: Array, P: Array, angles: Array) -> list[Array]:
    """Right-multipliers turning the pose ``T`` about its chord through ``P`` (2, 3) in {wm} by ``angles`` [rad]."""
    u = (P[1] - P[0]) / np.linalg.norm(P[1] - P[0])
    m = 0.5 * (P[0] + P[1])
    out = []
    for a in angles:
        D = np.eye(4)
        D[:3, :3] = cv2.Rodrigues(u * float(a))[0]
        D[:3, 3] = m - D[:3, :3] @ m
        out.append(D)
    return out


@dataclass(frozen=True)
class RollFit:
    """The best roll hypothesis: ``T_left_marker`` the absolute pose of {wm} in {ll} (refined with
    the corners and bars), ``ids`` (2,) the ring's corner ids of the chord's two corners,
    ``bars`` its bar samples found (both views), ``coded`` those of them on the code cells,
    ``runner_up`` and ``runner_up_coded`` the most of any rival (a hypothesis that puts the tip
    elsewhere, or one not refined),
    ``corners`` and ``bar_pairs`` what it was refined with (cvs.tracking.print_edges), its
    corners' and bars' RMS residual [px]."""

    T_left_marker: Array
    ids: NDArray[np.intp]
    bars: int
    coded: int
    runner_up: int
    runner_up_coded: int
    corners: Corners
    bar_pairs: Bars
    corner_rms_px: float
    bar_rms_px: float


def _bars(views: tuple[NDArray[np.uint8], NDArray[np.uint8]], camera: StereoCamera, T: Array,
          edges: PrintedEdges, blur_fit_px: float) -> Bars:
    found = [measure_edges(views[i], camera, i == 1, T, edges, blur_fit_px=blur_fit_px) for i in (0, 1)]
    return (bar_pairs(edges, found[0]), bar_pairs(edges, found[1]))


def _count(bars: Bars) -> int:
    return int(bars[0][0].shape[0] + bars[1][0].shape[0])


def _coded(bars: Bars, row_height: float) -> int:
    """The bar samples on the code cells (outside the checker rows, or along the sleeve): those
    whose place needs the roll."""
    n = 0
    for Pa, _, _, Pb, _, _ in bars:
        n += int(np.count_nonzero((np.abs(Pa[:, 2]) > row_height + 1e-9) | (np.abs(Pa[:, 2] - Pb[:, 2]) > 1e-9)))
    return n


def roll_hypotheses(views: tuple[NDArray[np.uint8], NDArray[np.uint8]], camera: StereoCamera, marker: MarkerModel,
                    edges: PrintedEdges, chord: StereoChord, axis: Array, corner_sigma_px: float,
                    bar_sigma_px: float, margin: float = 1.4, same_tip_m: float = 0.5e-3, window_deg: float = 15.0,
                    min_facing: float = 0.2, refine_top: int = 3, refine_max: int = 8, rounds: int = 3,
                    blur_fit_px: float = 0.0) -> RollFit | None:
    """Every roll hypothesis of the chord (its corners as ring corners a, a +- 1, for each a)
    started on the chord turned to within ``window_deg`` of ``axis`` (either sign) with both
    corners facing both cameras by ``min_facing``, scored by the bar samples of the print (code
    cells included) found in ``views`` at the best start. The ``refine_top`` best, and up to
    ``refine_max`` whose start has at least 1 / ``margin`` of the best start's samples, are
    refined ``rounds`` times with their bars (corners at ``corner_sigma_px``, bars at
    ``bar_sigma_px``; bars measured with ``blur_fit_px``, print_edges.measure_edges: 0, the largest gradient
    alone, by default, as the hypotheses' bars are measured many times and the blurred-step fit of the
    edges a wrong hypothesis refuses made the path ~6 x slower). The most bars wins.
    ``runner_up``: the most of any rival, a refined hypothesis whose tip lies more than ``same_tip_m`` from the
    winner's, or one not refined (at its start). Hypotheses that put the tip in the same place agree on it,
    whatever roll they name: the code decides the roll (MarkerTracker._two_pair_result). None without a start.
    """
    P = np.asarray(marker.corners(), float)
    n = marker.columns
    centres = (np.zeros(3), -np.asarray(camera.R, float).T @ np.asarray(camera.T, float).reshape(3))
    cos_w = math.cos(math.radians(window_deg))
    # the starts of corners 0, 1 on the chord; hypothesis (a, b) is start @ M: M P[a] = P[0], M P[b] = P[1]
    # (a roll for b = a + 1, and a half turn about x_wm after it for b = a - 1); the facing and the
    # axis' line of a start are the same for every hypothesis
    starts = [T for T in chord_starts(P[:2], chord.points, _TURNS)
              if abs(float(T[:3, 2] @ axis)) >= cos_w
              and min(float(corner_facing(T, P[:2], c).min()) for c in centres) >= min_facing]
    half_x = np.diag([1.0, -1.0, -1.0, 1.0])
    scored: list[tuple[int, Array, tuple[int, int], int]] = []  # samples, start, ids, coded samples
    for a in range(n):
        for step in (1, -1):
            ids = (a, (a + step) % n)
            M = roll_about_z(-a * marker.beta) if step == 1 else half_x @ roll_about_z(-a * marker.beta)
            best: tuple[int, Array, int] | None = None
            for T0 in starts:
                T = T0 @ M
                bars = _bars(views, camera, T, edges, blur_fit_px)
                k = _count(bars)
                if best is None or k > best[0]:
                    best = (k, T, _coded(bars, marker.row_height))
            if best is not None:
                scored.append((best[0], best[1], ids, best[2]))
    if not scored:
        return None
    scored.sort(key=lambda s: -s[0])
    chosen = [h for i, h in enumerate(scored[:refine_max]) if i < refine_top or h[0] * margin >= scored[0][0]]
    fits = []
    for _, T, ids, _ in chosen:
        sig = np.full(2, corner_sigma_px)
        corners: Corners = ((P[list(ids)], chord.uv_left, sig), (P[list(ids)], chord.uv_right, sig))
        bars = _bars(views, camera, T, edges, blur_fit_px)
        rc, rb = np.zeros(0), np.zeros(0)
        try:
            for i in range(rounds + 1):
                if _count(bars) < _MIN_REFINE_BARS:  # two corners leave the turn about their chord to the bars
                    raise np.linalg.LinAlgError("too few bars")
                T, rc, rb = refine_with_edges(camera, T, corners, bars, bar_sigma_px, iterations=3)
                if i < rounds:
                    bars = _bars(views, camera, T, edges, blur_fit_px)
        except np.linalg.LinAlgError:
            continue
        fits.append((_count(bars), T, ids, corners, bars, rc, rb, _coded(bars, marker.row_height)))
    if not fits:
        return None
    fits.sort(key=lambda f: (-f[0], -f[7]))
    k, T, ids, corners, bars, rc, rb, coded = fits[0]
    tip = np.asarray(marker.tip(), float)
    at = T[:3, :3] @ tip + T[:3, 3]
    refined = {f[2] for f in fits}
    rivals = [(f[0], f[7]) for f in fits[1:] if np.linalg.norm(f[1][:3, :3] @ tip + f[1][:3, 3] - at) > same_tip_m]
    rivals += [(c, cc) for c, _, other, cc in scored if other not in refined]
    corner_rms = float(np.sqrt(np.mean((rc * corner_sigma_px) ** 2))) if rc.size else 0.0
    bar_rms = float(np.sqrt(np.mean(rb ** 2))) if rb.size else 0.0
    return RollFit(T, np.asarray(ids, np.intp), k, coded, max([r[0] for r in rivals] + [0]),
                   max([r[1] for r in rivals] + [0]), corners, bars, corner_rms, bar_rms)
