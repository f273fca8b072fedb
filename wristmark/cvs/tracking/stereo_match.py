"""Stereo correspondence and relative indexing of marker corners (paper Sec. III.B(1)).

The corner points (not the images) are rectified with ``cv2.stereoRectify`` (computed once per
calibration) and ``cv2.undistortPoints`` with R1/P1, R2/P2. The marker axis is roughly
horizontal, so the corner circle runs vertically. With polarities (the detectors give them),
left and right corners within ``max_dy_px`` of rectified y and of equal polarity are paired and
both chains are indexed at once along their merged chain (``merged_chain_indices``: a corner
one image missed is bridged by the other, even two in a row). Without polarities each image's
corners are sorted by rectified y, consecutive corners get consecutive relative indices, and
the two chains are aligned by the index offset that pairs the most corners. In both, a step of
2 where the polarity does not alternate (a corner missed in both images). Indices are
relative: the absolute roll about z_wm is unknown (module doc of cvs.tracking.stereo_pose); the
polarity fixes their parity (even index <=> polarity +1 in the left chain).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.errors import InputError

Array = NDArray[np.float64]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class StereoMatch:
    """Relative marker corner indices per detected corner (-1: rejected) and the matched pairs.

    index_left (n_l,), index_right (n_r,): relative corner index of each input corner or -1;
    pairs (m, 2): rows (left row, right row) of matched corners; dy_px (m,): rectified
    y difference right - left of each pair [px]; rect_left (n_l, 2), rect_right (n_r, 2):
    rectified pixels.
    """

    index_left: IntArray
    index_right: IntArray
    pairs: IntArray
    dy_px: Array
    rect_left: Array
    rect_right: Array

    @property
    def n_pairs(self) -> int:
        """Number of left/right pairs."""
        return int(self.pairs.shape[0])


class StereoRectifier:
    """Rectification of corner points for one calibration (cv2.stereoRectify once)."""

    def __init__(self, camera: StereoCamera) -> None:
        self.camera = camera
        try:
            R1, R2, P1, P2, *_ = cv2.stereoRectify(
                np.asarray(camera.left.K, float),
                np.asarray(camera.left.dist, float),
                np.asarray(camera.right.K, float),
                np.asarray(camera.right.dist, float),
                tuple(int(v) for v in camera.image_size),
                np.asarray(camera.R, float),
                np.asarray(camera.T, float).reshape(3, 1),
                flags=cv2.CALIB_ZERO_DISPARITY,
                alpha=-1,
            )
        except cv2.error as e:
            raise InputError(f"cv2.stereoRectify failed on this calibration: {e.err}") from e
        self.R1: Array = np.asarray(R1, float)
        self.R2: Array = np.asarray(R2, float)
        self.P1: Array = np.asarray(P1, float)
        self.P2: Array = np.asarray(P2, float)
        self._crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)

    def _rect(self, uv: Array, K: Array, dist: Array, R: Array, P: Array) -> Array:
        pts = np.asarray(uv, float).reshape(-1, 1, 2)
        if pts.shape[0] == 0:
            return np.zeros((0, 2))
        out = cv2.undistortPoints(pts, np.asarray(K, float), np.asarray(dist, float), None, R, P, self._crit)
        return np.asarray(out, dtype=np.float64).reshape(-1, 2)

    def left(self, uv_raw: Array) -> Array:
        """Raw left pixels Nx2 -> rectified pixels Nx2."""
        c = self.camera.left
        return self._rect(uv_raw, c.K, c.dist, self.R1, self.P1)

    def right(self, uv_raw: Array) -> Array:
        """Raw right pixels Nx2 -> rectified pixels Nx2."""
        c = self.camera.right
        return self._rect(uv_raw, c.K, c.dist, self.R2, self.P2)


def chain_indices(y: Array, polarity: IntArray | None) -> IntArray:
    """Relative indices along a corner chain sorted by y: step 1 between consecutive corners,
    2 where the polarity repeats (a corner in between was missed). The first corner (smallest y)
    gets 0 if its polarity is +1 (or unknown), else 1."""
    order = np.argsort(y, kind="stable")
    idx = np.zeros(y.size, int)
    if y.size == 0:
        return idx
    cur = 0 if polarity is None or polarity[order[0]] > 0 else 1
    idx[order[0]] = cur
    for a, b in zip(order[:-1], order[1:]):
        same = polarity is not None and polarity[a] == polarity[b]
        cur += 2 if same else 1
        idx[b] = cur
    return idx


def merged_chain_indices(yl: Array, pl: IntArray, yr: Array, pr: IntArray, max_dy_px: float
                         ) -> tuple[IntArray, IntArray]:
    """Relative indices of both chains at once, along the merged chain on the rectified y axis.

    A left and a right corner that are each other's nearest within ``max_dy_px`` and of equal
    polarity are one marker corner (a stereo pair); a corner seen in one image only joins the
    merged chain at its own y, unless another corner of the same polarity lies within
    3 max_dy_px (a pair that failed the y test: rejected, -1). A corner missed in one image is
    then bridged by the other image; where both miss it the repeated polarity steps by 2
    (chain_indices). With no pair at all every index is -1."""
    il, ir = -np.ones(yl.size, int), -np.ones(yr.size, int)
    d = np.abs(yr[None, :] - yl[:, None])
    dd = np.where((d <= max_dy_px) & (pl[:, None] == pr[None, :]), d, np.inf)
    pairs = [(a, int(np.argmin(dd[a]))) for a in range(yl.size) if yr.size and np.isfinite(dd[a].min())]
    pairs = [(a, b) for a, b in pairs if int(np.argmin(dd[:, b])) == a]  # mutual nearest
    if not pairs:
        return il, ir
    # entries of the merged chain: (y, polarity, left row or -1, right row or -1)
    merged = [(0.5 * (yl[a] + yr[b]), int(pl[a]), a, b) for a, b in pairs]
    in_l, in_r = {a for a, _ in pairs}, {b for _, b in pairs}
    singles = [(float(yl[a]), int(pl[a]), a, -1) for a in range(yl.size) if a not in in_l]
    singles += [(float(yr[b]), int(pr[b]), -1, b) for b in range(yr.size) if b not in in_r]
    for k, e in enumerate(singles):
        rivals = merged[: len(pairs)] + singles[:k] + singles[k + 1 :]
        if not any(abs(e[0] - o[0]) < 3.0 * max_dy_px and e[1] == o[1] for o in rivals):
            merged.append(e)
    merged.sort(key=lambda e: e[0])
    idx = chain_indices(np.array([e[0] for e in merged]), np.array([e[1] for e in merged], int))
    for k, (_, _, a, b) in enumerate(merged):
        if a >= 0:
            il[a] = idx[k]
        if b >= 0:
            ir[b] = idx[k]
    return il, ir


def _check(uv: Array, pol: IntArray | None, name: str) -> tuple[Array, IntArray | None]:
    a = np.asarray(uv, float)
    if a.size == 0:
        a = a.reshape(0, 2)
    if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
        raise InputError(f"{name} corners must be a finite (N, 2) pixel array, got shape {a.shape}")
    if pol is None:
        return a, None
    p = np.asarray(pol).reshape(-1).astype(int)
    if p.size != a.shape[0] or not np.all(np.abs(p) == 1):
        raise InputError(f"{name} polarity must be N values of +1/-1 matching the corners")
    return a, p


def match_corners(
    rectifier: StereoRectifier,
    corners_left: Array,
    corners_right: Array,
    polarity_left: IntArray | None = None,
    polarity_right: IntArray | None = None,
    max_dy_px: float = 2.0,
) -> StereoMatch:
    """Pair left/right raw corner pixels by rectified y and give them consistent relative indices.

    Corners seen in one image only keep the index the (merged) chain gives them; a corner whose
    partner is more than ``max_dy_px`` away in rectified y (or of the other polarity) is
    rejected (-1). With no pair at all every index is -1.
    """
    ul, pl = _check(corners_left, polarity_left, "left")
    ur, pr = _check(corners_right, polarity_right, "right")
    if not max_dy_px > 0:
        raise InputError(f"max_dy_px must be > 0, got {max_dy_px}")
    rl, rr = rectifier.left(ul), rectifier.right(ur)
    if pl is not None and pr is not None:
        il, ir = merged_chain_indices(rl[:, 1], pl, rr[:, 1], pr, max_dy_px)
        P = np.array([(a, int(np.flatnonzero(ir == il[a])[0])) for a in range(il.size)
                      if il[a] >= 0 and np.any(ir == il[a])], int).reshape(-1, 2)
        dy = rr[P[:, 1], 1] - rl[P[:, 0], 1] if P.size else np.zeros(0)
        return StereoMatch(il, ir, P, np.asarray(dy, float), rl, rr)
    il, ir = chain_indices(rl[:, 1], pl), chain_indices(rr[:, 1], pr)
    best: tuple[int, float, int] | None = None  # (-count, sum |dy|, offset)
    for off in range(
        int(il.min(initial=0)) - int(ir.max(initial=0)), int(il.max(initial=0)) - int(ir.min(initial=0)) + 1
    ):
        if pl is not None and pr is not None and off % 2:
            continue  # chains start at the parity of their first polarity: odd offsets pair opposite polarities
        count, tot = 0, 0.0
        for b in range(ir.size):
            a = np.flatnonzero(il == ir[b] + off)
            if a.size:
                dy = abs(rr[b, 1] - rl[a[0], 1])
                if dy <= max_dy_px:
                    count += 1
                    tot += dy
        key = (-count, tot, off)
        if count and (best is None or key < best):
            best = key
    if best is None:
        neg = -np.ones(ul.shape[0], int), -np.ones(ur.shape[0], int)
        return StereoMatch(neg[0], neg[1], np.zeros((0, 2), int), np.zeros(0), rl, rr)
    off = best[2]
    ir = ir + off
    pairs: list[tuple[int, int]] = []
    for b in range(ir.size):
        a = np.flatnonzero(il == ir[b])
        if a.size:
            if abs(rr[b, 1] - rl[a[0], 1]) <= max_dy_px:
                pairs.append((int(a[0]), b))
            else:
                il[a[0]], ir[b] = -1, -1
    P = np.array(pairs, int).reshape(-1, 2)
    dy = rr[P[:, 1], 1] - rl[P[:, 0], 1] if P.size else np.zeros(0)
    return StereoMatch(il, ir, P, np.asarray(dy, float), rl, rr)
