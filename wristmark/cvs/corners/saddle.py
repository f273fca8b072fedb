"""A small fallback X-corner chain detector (Hessian saddle + Newton sub-pixel saddle), used by
the tracker only when ``cvs.corners.detector`` (the paper's detector, eq. 6-10) is not
available, and as a baseline in bench/tracking.py.

Saddle response S = Ixy^2 - Ixx Iyy on a Gaussian-smoothed image, 7x7 non-maximum suppression,
an X-shape test (half-turn symmetry), sub-pixel saddle point by Newton steps, polarity = sign
of Ixy (image axes: the marker's patch edges are roughly horizontal and vertical when its axis
is horizontal), then the longest vertical chain of
alternating polarity (the corner circle runs vertically). Same result type as the paper's
detector: ``corners`` (N, 2) raw pixels ordered along the chain and ``polarity`` (N,) +-1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SaddleSettings:
    """blur_sigma [px]; rel_threshold: saddle response relative to the ROI maximum; max_step_px:
    largest distance between consecutive marker corners [px]; roi_margin_px: ROI margin around
    the previous corners [px]; max_candidates: strongest responses kept; x_symmetry: least
    correlation of a candidate's patch with its half-turn rotation [-]."""

    blur_sigma: float = 1.0
    rel_threshold: float = 0.08
    max_step_px: float = 60.0
    roi_margin_px: int = 60
    max_candidates: int = 60
    min_corners: int = 3
    x_symmetry: float = 0.6


@dataclass(frozen=True)
class SaddleDetection:
    """corners (N, 2) raw pixels along the chain, polarity (N,) +-1, response (N,)."""

    corners: Array
    polarity: NDArray[np.int_]
    response: Array


def _bilinear(a: NDArray[Any], x: float, y: float) -> float:
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0
    return float(
        a[y0, x0] * (1 - fx) * (1 - fy)
        + a[y0, x0 + 1] * fx * (1 - fy)
        + a[y0 + 1, x0] * (1 - fx) * fy
        + a[y0 + 1, x0 + 1] * fx * fy
    )


def _saddle_refine(
    f: NDArray[Any], ixx: NDArray[Any], iyy: NDArray[Any], ixy: NDArray[Any], pts: Array
) -> tuple[Array, NDArray[np.bool_]]:
    """Sub-pixel X-corners as the saddle point of the smoothed image: Newton steps
    x <- x - H^-1 grad I with bilinearly interpolated derivatives (measured on rendered marker
    corners: 0.095 px RMS against 0.27 px for cv2.cornerSubPix). Points that move more than
    1.5 px or leave the image are flagged False."""
    ix = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3)
    iy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3)
    h, w = f.shape
    out = pts.astype(np.float64).copy()
    good = np.ones(len(pts), bool)
    for k, (x, y) in enumerate(out):
        for _ in range(5):
            if not (1 <= x < w - 2 and 1 <= y < h - 2):
                good[k] = False
                break
            g = np.array([_bilinear(ix, x, y), _bilinear(iy, x, y)]) / 8.0  # Sobel 3x3 gain 8
            hxy = _bilinear(ixy, x, y) / 4.0
            H = np.array([[_bilinear(ixx, x, y) / 4.0, hxy], [hxy, _bilinear(iyy, x, y) / 4.0]])
            if np.linalg.det(H) >= 0:  # not a saddle here
                good[k] = False
                break
            d = np.clip(-np.linalg.solve(H, g), -1.0, 1.0)
            x, y = x + d[0], y + d[1]
        out[k] = x, y
        good[k] &= bool(np.hypot(*(out[k] - pts[k])) <= 1.5)
    return out, good


def _gray(img: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img, np.uint8)


class SaddleCornerDetector:
    """Detect the marker's corner chain; ``track`` searches a ROI around the last result."""

    def __init__(self, settings: SaddleSettings | None = None) -> None:
        self.settings = settings or SaddleSettings()
        self._last: Array | None = None

    def detect(self, gray: NDArray[np.uint8], roi: tuple[int, int, int, int] | None = None) -> SaddleDetection:
        """Whole image (or roi = (x, y, w, h)) -> the longest alternating vertical chain."""
        x0, y0 = 0, 0
        img = np.asarray(gray)
        if roi is not None:  # crop first, then convert only the box
            x0, y0, w, h = roi
            img = img[y0 : y0 + h, x0 : x0 + w]
        g = _gray(img)
        s = self.settings
        f = cv2.GaussianBlur(g.astype(np.float32), (0, 0), s.blur_sigma)
        ixx = cv2.Sobel(f, cv2.CV_32F, 2, 0, ksize=3)
        iyy = cv2.Sobel(f, cv2.CV_32F, 0, 2, ksize=3)
        ixy = cv2.Sobel(f, cv2.CV_32F, 1, 1, ksize=3)
        S = ixy * ixy - ixx * iyy
        peak = float(S.max()) if S.size else 0.0
        empty = SaddleDetection(np.zeros((0, 2)), np.zeros(0, int), np.zeros(0))
        if peak <= 1.0:
            self._last = None
            return empty
        nms = (S >= cv2.dilate(S, np.ones((7, 7), np.uint8))) & (s.rel_threshold * peak < S)
        ys, xs = np.nonzero(nms)
        if xs.size > s.max_candidates:
            keep = np.argsort(S[ys, xs])[::-1][: s.max_candidates]
            ys, xs = ys[keep], xs[keep]
        if xs.size < s.min_corners:
            self._last = None
            return empty
        xshape = self._x_shaped(g, xs, ys)
        xs, ys = xs[xshape], ys[xshape]
        if xs.size < s.min_corners:
            self._last = None
            return empty
        pts = np.column_stack([xs, ys]).astype(np.float64)
        pol = np.where(ixy[ys, xs] > 0, 1, -1)
        resp = S[ys, xs].astype(np.float64)
        chain = self._chain(pts, pol, resp)
        if len(chain) < s.min_corners:
            self._last = None
            return empty
        sub, good = _saddle_refine(f, ixx, iyy, ixy, pts[chain])
        chain = [c for c, k in zip(chain, good) if k]
        if len(chain) < s.min_corners:
            self._last = None
            return empty
        c = sub[good] + [x0, y0]
        self._last = c
        return SaddleDetection(c, pol[chain], resp[chain])

    def _x_shaped(self, g: NDArray[np.uint8], xs: NDArray[np.int_], ys: NDArray[np.int_]) -> NDArray[np.bool_]:
        """X-corner test on an 11x11 patch: symmetric under a half turn (correlation with its
        180-degree rotation >= x_symmetry) and swapped under a quarter turn (negative correlation
        with its 90-degree rotation). Rejects L/T junctions at the sleeve's borders."""
        r = 5
        ok = np.zeros(xs.size, bool)
        h, w = g.shape
        for k, (x, y) in enumerate(zip(xs, ys)):
            if x < r or y < r or x >= w - r or y >= h - r:
                continue
            p = g[y - r : y + r + 1, x - r : x + r + 1].astype(np.float64)
            p -= p.mean()
            n = float(np.sum(p * p))
            if n <= 0:
                continue
            c180 = float(np.sum(p * p[::-1, ::-1])) / n
            c90 = float(np.sum(p * np.rot90(p))) / n
            ok[k] = c180 >= self.settings.x_symmetry and c90 < 0
        return ok

    def _chain(self, pts: Array, pol: NDArray[np.int_], resp: Array) -> list[int]:
        """Longest path by increasing y, alternating polarity, mostly vertical steps."""
        order = np.argsort(pts[:, 1])
        n = order.size
        best_len = np.ones(n, int)
        best_score = resp[order].copy()
        prev = -np.ones(n, int)
        for j in range(n):
            b = order[j]
            for i in range(j):
                a = order[i]
                d = pts[b] - pts[a]
                if pol[a] == pol[b] or d[1] <= 0 or abs(d[0]) > 0.8 * d[1] + 2.0:
                    continue
                if np.hypot(*d) > self.settings.max_step_px:
                    continue
                cand = (best_len[i] + 1, best_score[i] + resp[b])
                if cand > (best_len[j], best_score[j]):
                    best_len[j], best_score[j], prev[j] = cand[0], cand[1], i
        j = int(np.lexsort((best_score, best_len))[-1])
        out = []
        while j >= 0:
            out.append(int(order[j]))
            j = int(prev[j])
        return out[::-1]

    def track(self, gray: NDArray[np.uint8]) -> SaddleDetection:
        """ROI around the previous corners when there are some, else the whole frame (grey or BGR:
        in the ROI only the box is converted)."""
        img = np.asarray(gray)
        box = self.previous_roi(img.shape)
        if box is not None:
            det = self.detect(img, box)
            if det.corners.shape[0] >= self.settings.min_corners:
                return det
        return self.detect(_gray(img))

    def follow(self, corners: Array) -> None:
        """Centre the next ROI search on ``corners`` (N, 2) [px] found otherwise (e.g. by another
        detector in this pair); fewer than two forget the ROI."""
        c = np.asarray(corners, float).reshape(-1, 2)
        self._last = c.copy() if c.shape[0] >= 2 else None

    def previous_roi(self, shape: tuple[int, ...]) -> tuple[int, int, int, int] | None:
        """The box (x, y, w, h) [px] that ``track`` searches first in an image of ``shape`` (rows,
        cols, ...): the previous corners plus ``roi_margin_px``; None when there are none."""
        if self._last is None:
            return None
        m = self.settings.roi_margin_px
        lo = np.maximum(np.floor(self._last.min(axis=0)) - m, 0).astype(int)
        hi = np.minimum(np.ceil(self._last.max(axis=0)) + m, [shape[1] - 1, shape[0] - 1]).astype(int)
        return int(lo[0]), int(lo[1]), int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)

    def reset(self) -> None:
        """Forget the ROI (next ``track`` searches the whole frame)."""
        self._last = None
