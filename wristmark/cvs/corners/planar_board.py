"""Ordering the X-corners of a planar chessboard like ``cv2.findChessboardCornersSB``.

``assemble_grid`` takes the X-corners of an image (cvs.corners.detector.detect_xcorners) and
returns the inner corners of a columns x rows board row by row, or None. Used to compare the
paper's corner stage with OpenCV on real photographs (bench/real_chessboard.py). Image frame as
in cvs.corners.xcorners.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.corners.xcorners import Array, XCorners
from wristmark.cvs.gray_image import check_image, to_gray


def _unit(a: float) -> Array:
    return np.array([math.cos(a), math.sin(a)])


def assemble_grid(
    xc: XCorners, pattern: tuple[int, int] = (9, 6), gray: NDArray[np.uint8] | None = None, tol: float = 0.3
) -> Array | None:
    """Order the X-corners of a planar chessboard with ``pattern`` = (columns, rows) inner
    corners like cv2.findChessboardCornersSB: (columns * rows, 2) [px] row by row, or None.

    A lattice is grown breadth-first from strong corners: each step along a corner's two edges is
    predicted from the last step, and a corner of the other polarity within ``tol`` x step of the
    prediction is taken. A complete columns x rows lattice is ordered with step a along a row and
    b across rows such that a x b > 0 in the image (x right, y down: a proper board pose, not a
    mirror image) and, given ``gray``, the square between +a and +b at the first corner is bright
    (what findChessboardCornersSB does on OpenCV's sample boards), else the first corner is the one
    nearest the image origin.
    """
    cols, rows = pattern
    pts, n = xc.corners, xc.corners.shape[0]
    if n < cols * rows:
        return None
    for seed in range(min(n, 20)):
        lab = _grow_lattice(xc, seed, tol)
        if lab is None or len(lab) < cols * rows:
            continue
        grid = _fit_pattern(lab, pts, cols, rows)
        if grid is not None:
            return _orient_grid(grid, gray).reshape(-1, 2)
    return None


def _grow_lattice(xc: XCorners, seed: int, tol: float) -> dict[tuple[int, int], int] | None:
    """Integer lattice labels (i, j) -> corner row, grown breadth-first from ``seed``."""
    pts = xc.corners
    p0 = pts[seed]
    steps = []
    for a in xc.edges[seed]:
        u = _unit(a)
        d = (pts - p0) @ u
        off = np.abs((pts - p0) @ np.array([-u[1], u[0]]))
        ok = (d > 3.0) & (off < 0.25 * np.maximum(d, 1.0)) & (xc.polarity != xc.polarity[seed])
        if not np.any(ok):
            return None
        k = int(np.flatnonzero(ok)[np.argmin(d[ok])])
        steps.append(pts[k] - p0)
    labels: dict[tuple[int, int], int] = {(0, 0): seed}
    vecs: dict[tuple[int, int], tuple[Array, Array]] = {(0, 0): (steps[0], steps[1])}
    taken = {seed}
    queue = [(0, 0)]
    while queue:
        ij = queue.pop(0)
        k = labels[ij]
        a, b = vecs[ij]
        for di, dj, v in ((1, 0, a), (-1, 0, -a), (0, 1, b), (0, -1, -b)):
            nij = (ij[0] + di, ij[1] + dj)
            if nij in labels:
                continue
            d = np.hypot(*(pts - (pts[k] + v)).T)
            q = int(np.argmin(d))
            if d[q] > tol * float(np.hypot(*v)) or q in taken or xc.polarity[q] == xc.polarity[k]:
                continue
            labels[nij] = q
            taken.add(q)
            step = pts[q] - pts[k]
            vecs[nij] = (step * di, b) if di else (a, step * dj)
            queue.append(nij)
    return labels


def _fit_pattern(lab: dict[tuple[int, int], int], pts: Array, cols: int, rows: int) -> Array | None:
    """The complete lattice window of cols x rows (either way round) as a (rows, cols, 2) grid
    whose rows run along the long side; None if there is none or more than one."""
    found = None
    for wi, wj in ((cols, rows), (rows, cols)):
        for i0, j0 in lab:
            if all((i0 + i, j0 + j) in lab for i in range(wi) for j in range(wj)):
                g = np.array([[pts[lab[(i0 + i, j0 + j)]] for i in range(wi)] for j in range(wj)])
                if found is not None:
                    return None
                found = g if wi == cols else g.transpose(1, 0, 2)
    return found


def _orient_grid(grid: Array, gray: NDArray[np.uint8] | None) -> Array:
    """Reorder a (rows, cols, 2) grid as described in assemble_grid."""
    a = grid[0, 1] - grid[0, 0]
    b = grid[1, 0] - grid[0, 0]
    if a[0] * b[1] - a[1] * b[0] < 0:  # mirrored labelling: reverse the rows
        grid = grid[::-1]
        a, b = grid[0, 1] - grid[0, 0], grid[1, 0] - grid[0, 0]
    if gray is not None:
        sm = cv2.GaussianBlur(to_gray(check_image(gray)), (5, 5), 0)
        h, w = sm.shape

        def grey(p: Array) -> float:
            x, y = int(np.clip(round(p[0]), 0, w - 1)), int(np.clip(round(p[1]), 0, h - 1))
            return float(sm[y, x])

        p0 = grid[0, 0]
        flip = grey(p0 + 0.35 * (a + b)) < grey(p0 + 0.35 * (a - b))
    else:
        flip = float(grid[-1, -1].sum()) < float(grid[0, 0].sum())
    return grid[::-1, ::-1] if flip else grid
