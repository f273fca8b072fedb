"""The paper's marker-corner detector (Sec. III.A, eq. 6-10, Fig. 4) with ROI tracking.

Image frame: raw (distorted) pixels, x right, y down, pixel (0, 0) is the centre of the top-left
pixel; angles in radians measured from +x towards +y. Grey levels are scaled to [0, 1].

Pipeline per image (or region of interest), one module per step:

1. Corner likelihood (eq. 6, cvs.corners.likelihood). The image is smoothed (Gaussian,
   ``smooth_sigma``) and 3x3 Sobel kernels, normalised to unit gain, give I_x, I_y, I_xx, I_yy,
   I_xy; CL = max(c_xy, c_45), eps = 2, from the axis-aligned and diagonal derivatives.
2. Non-maximum suppression in 5x5; a peak is a candidate when its *normalised* CL, CL divided by
   the local grey-level range of its 11x11 neighbourhood (floored at ``contrast_floor``), is at
   least 0.06: the same threshold then works for dim and bright markers.
3. Edge orientations (eq. 7, cvs.corners.xcorner_test): gradient angle atan2(I_y, I_x) mod pi weighted
   by the gradient norm in the 11x11 neighbourhood (the paper's 10x10 window, centred on the
   pixel) -> 32-bin histogram -> its two strongest modes, each refined by mean shift.
4. Hyperbolic-tangent model (HTM) tanh(u_a/s) tanh(u_b/s) with the two edges, correlated with the
   grey levels of the same neighbourhood (eq. 8, a correlation coefficient); |CC| >= 0.8 is an
   X-corner, sign(CC) its polarity. Polarity convention: edge a is the edge closer to vertical,
   oriented downwards, edge b the other one, oriented to the right; polarity +1 when the sector
   between them (bottom-right for an axis-aligned corner) is bright, i.e. the sign of I_xy there.
5. The marker chain (Fig. 4, cvs.corners.chain): candidates in decreasing CL order until one is
   an X-corner; the second corner is the nearest found by moving the window along the four edge
   directions; then the chain grows outward both ways along the local edge direction closest to
   the last step until the searched distance exceeds twice the last spacing. Consecutive corners
   alternate in polarity taken along the chain (cvs.corners.chain.along_polarity: the convention
   above flips where a steeply seen sleeve's edges both lean ~45 deg) and their edges across the
   chain agree within ``cross_edge_tol_deg``; the chain's polarities are given so
   (docs/notes/steep-views.md). Output order: along the chain, first corner = the end with the
   smaller y.
6. Sub-pixel position (cvs.corners.subpixel): the quadric S = ax^2 + by^2 + cx + dy + exy + f
   fitted by least squares to the 7x7 CL patch and its extremum (eq. 9-10), kept in
   ``corners_quadric``. Beyond the paper (``refine``, default on): a Gauss-Newton fit of the HTM
   grey-level model itself (centre, both edge angles, edge width, grey offset, contrast, linear
   shading) in a 9x9 window, started at the integer CL peak. Measured on rendered 1080p marker
   images: eq. 10 gives ~0.57 px RMS (worse than the integer peak, ~0.43 px: CL is too sharply
   peaked for a 7x7 quadric), the HTM fit ~0.06 px; on OpenCV's real stereo samples it also beats
   findChessboardCornersSB in stereoCalibrate RMS (bench/real_chessboard.py).
7. ROI tracking (paper III.A(1)): ``track`` searches a box around the previous frame's corners
   and the whole frame when there are none or the box loses the marker. Only the box (plus the
   filters' margin) is cropped and converted to grey: a colour frame costs no whole-frame work
   in ROI mode. Beyond the paper, a cold whole-frame search of a large image first runs on a 2x
   smaller copy (``coarse_scale``) and is then redone at full resolution in the box around what
   it found (falls back to the full-resolution whole frame when the small copy shows no chain).

``detect_xcorners`` returns every X-corner of an image (steps 1-4 and 6) and ``assemble_grid``
(cvs.corners.planar_board) orders those of a planar chessboard like ``cv2.findChessboardCornersSB``.
ROIs are (x, y, w, h) as in cvs.corners.saddle. The per-candidate loops are numba-compiled
(cached on disk; loaded once per process on first use, or ahead of it by ``wristmark.warm_up``).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.corners.chain import along_polarity, find_chain, find_pairs
from wristmark.cvs.corners.likelihood import CornerCandidates, Image, Workspace, corner_likelihood, find_candidates
from wristmark.cvs.corners.planar_board import assemble_grid
from wristmark.cvs.corners.subpixel import chain_spacing, htm_refine, quadric_subpixel, subpixel
from wristmark.cvs.corners.xcorner_test import check_xcorners
from wristmark.cvs.corners.xcorners import Array, CornerChain, DetectorSettings, Roi, XCorners, scaled_settings
from wristmark.cvs.gray_image import check_image, gray_crop, to_gray
from wristmark.models.errors import InputError

__all__ = [
    "BOARD_SETTINGS",
    "CornerChain",
    "CornerCandidates",
    "DetectorSettings",
    "Image",
    "MarkerCornerDetector",
    "Roi",
    "Workspace",
    "XCorners",
    "assemble_grid",
    "corner_likelihood",
    "detect_xcorners",
    "htm_refine",
    "quadric_subpixel",
]

BOARD_SETTINGS = DetectorSettings(cl_threshold=0.03)
"""detect_xcorners' default: a planar board is seen at any in-plane rotation, and eq. 6's two
fixed orientations (0 and 45 degrees) give corners rotated by ~22 degrees a weaker CL (on OpenCV's
stereo samples 6 of 1404 corners have a normalised CL between 0.049 and 0.06); the HTM test still
decides."""


def detect_xcorners(gray: NDArray[np.uint8], settings: DetectorSettings | None = None) -> XCorners:
    """Every X-corner of a grayscale (or BGR) uint8 image: CL, NMS, HTM test and sub-pixel fit;
    rows in decreasing normalised CL. Default settings: ``BOARD_SETTINGS``."""
    s = settings or BOARD_SETTINGS
    cands = find_candidates(to_gray(check_image(gray)), s)
    idx = np.arange(cands.xs.size)
    check_xcorners(cands, idx, s)
    idx = idx[cands.ok[idx]]
    if idx.size == 0:
        return XCorners.empty()
    pts = cands.points(idx)
    d = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1)) + np.diag(np.full(idx.size, np.inf))
    ref, q, e = subpixel(cands, idx, s, d.min(axis=1))
    return XCorners(ref, q, cands.pol[idx].copy(), cands.cc[idx].copy(), cands.cln[idx].copy(), e)


def _roi_box(pts: Array, margin: float, shape: tuple[int, int]) -> Roi:
    h, w = shape
    lo = np.maximum(np.floor(pts.min(axis=0) - margin), 0).astype(int)
    hi = np.minimum(np.ceil(pts.max(axis=0) + margin), [w - 1, h - 1]).astype(int)
    return int(lo[0]), int(lo[1]), int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)


def run_kernels_once() -> None:
    """Run every compiled kernel of the detector once on a small synthetic corner, so that
    numba's set-up and its disk cache are paid now rather than on a first frame (measured:
    ~0.3-0.4 s once per process, mostly numba's own start; the first run after an install or a
    change of the kernels compiles them, ~12 s, into cvs/__pycache__). Called by
    :func:`cvs.tracking.warmup.warm_up`; building a detector does not call it."""
    yy, xx = np.mgrid[0:48, 0:48]
    corner = np.where((xx < 24.3) == (yy < 23.6), 200, 40).astype(np.uint8)
    img = np.asarray(cv2.GaussianBlur(corner, (5, 5), 1.0), np.uint8)
    detect_xcorners(img)  # CL, NMS, X-corner test, quadric and HTM fit
    det = MarkerCornerDetector()
    det.detect(img)  # the chain search
    det.chains_of_two(img)  # and its chains of two


class MarkerCornerDetector:
    """The paper's marker-corner detector with ROI tracking (same interface as
    cvs.corners.saddle.SaddleCornerDetector: ``detect``, ``track``, ``reset``); images are uint8
    grey (h, w) or BGR / BGRA (h, w, 3 | 4) [px]."""

    def __init__(self, settings: DetectorSettings | None = None) -> None:
        self.settings = settings or DetectorSettings()
        self._last: Array | None = None
        self._ws = Workspace()
        # the last search's candidates, settings and image origin (for retry_with_gaps)
        self._searched: tuple[CornerCandidates, DetectorSettings, int, int, float] | None = None

    def _chain_in(
        self, img: NDArray[np.uint8], roi: Roi | None, s: DetectorSettings, times: dict[str, float],
        magnify: float = 1.0,
    ) -> XCorners:
        """Chain in the whole image or in roi (x, y, w, h), full-image pixels. Only roi plus the
        filters' margin is converted to grey, so that filters inside roi equal the whole-frame
        ones; with ``magnify`` > 1 (roi only) that crop is enlarged so many times (bicubic) before
        the search. Adds the stages' wall times [ms] to ``times``."""
        t0 = time.perf_counter()
        x0 = y0 = 0
        inner = None
        if roi is None:
            g = to_gray(img)
        else:
            h, w = img.shape[:2]
            pad = int(math.ceil((math.ceil(3 * s.smooth_sigma) + s.half_window + s.quad_size + 2) / magnify)) + 1
            x, y, rw, rh = roi
            x0, y0 = max(x - pad, 0), max(y - pad, 0)
            g = gray_crop(img, (x0, y0, min(x + rw + pad, w), min(y + rh + pad, h)))
            inner = (x - x0, y - y0, rw, rh)
            if magnify > 1.0:
                g = np.asarray(cv2.resize(g, None, fx=magnify, fy=magnify, interpolation=cv2.INTER_CUBIC), np.uint8)
                lo = [int(math.floor((v + 0.5) * magnify - 0.5)) for v in inner[:2]]
                inner = (lo[0], lo[1], int(math.ceil(rw * magnify)), int(math.ceil(rh * magnify)))
        t1 = time.perf_counter()
        cands = find_candidates(g, s, inner, self._ws)
        t2 = time.perf_counter()
        chain = find_chain(cands, s)
        t3 = time.perf_counter()
        for key, dt in (("gray_ms", t1 - t0), ("candidates_ms", t2 - t1), ("chain_ms", t3 - t2)):
            times[key] = times.get(key, 0.0) + 1e3 * dt
        self._searched = (cands, s, x0, y0, magnify)
        return self._corners(cands, chain, s, x0, y0, times, magnify)

    def _corners(self, cands: CornerCandidates, chain: Any, s: DetectorSettings, x0: int, y0: int,
                 times: dict[str, float], magnify: float = 1.0) -> XCorners:
        """The chain's sub-pixel corners in full-image pixels (the searched image's origin at
        (x0, y0), enlarged ``magnify`` times), first corner the end with the smaller y; empty for a
        chain under min_corners."""
        t3 = time.perf_counter()
        if chain.size < s.min_corners:
            return XCorners.empty()
        ref, q, e = subpixel(cands, chain, s, chain_spacing(cands.points(chain)))
        times["subpixel_ms"] = times.get("subpixel_ms", 0.0) + 1e3 * (time.perf_counter() - t3)
        off = np.array([x0, y0], float)
        ref, q = (ref + 0.5) / magnify - 0.5 + off, (q + 0.5) / magnify - 0.5 + off
        pts = cands.points(chain)
        step = np.gradient(pts, axis=0)  # the chain's direction at each corner (ends: their step)
        pol = along_polarity(cands.pol[chain], cands.edges[chain], step) if s.chain_polarity == "along" else (
            cands.pol[chain].copy())
        xc = XCorners(ref, q, pol, cands.cc[chain].copy(), cands.cln[chain].copy(), e)
        return xc if xc.corners[0, 1] <= xc.corners[-1, 1] else xc.take(np.arange(chain.size)[::-1])

    def retry_with_gaps(self) -> CornerChain:
        """The chain of the last search's candidates (whole frame or ROI, as searched last) that may
        step over ``settings.max_gaps`` missed corners (cvs.corners.chain): the tracker's last try on
        a pair whose chains were too short (a highlight over the corner the camera sees best). No
        new image search; the ROI follows the result. Empty without a search or with max_gaps 0."""
        t0 = time.perf_counter()
        extras: dict[str, float] = {}
        return self._result(self._gap_chain(extras), None, t0, extras)

    def _gap_chain(self, extras: dict[str, float]) -> XCorners:
        """:meth:`retry_with_gaps`'s corners (the last search's candidates and settings)."""
        if self._searched is None or self._searched[1].max_gaps <= 0:
            return XCorners.empty()
        t0 = time.perf_counter()
        cands, s, x0, y0, magnify = self._searched
        chain = find_chain(cands, s, s.max_gaps)
        extras["chain_ms"] = extras.get("chain_ms", 0.0) + 1e3 * (time.perf_counter() - t0)
        return self._corners(cands, chain, s, x0, y0, extras, magnify)

    def retry_in_box(self, gray: Any, roi: Roi, cl_scale: float) -> CornerChain:
        """The marker chain in ``roi`` = (x, y, w, h) [px] of a uint8 grey or BGR image, its
        candidates kept down to ``cl_scale`` (0-1] times the CL threshold and the chain stepping
        over ``settings.max_gaps`` missed corners: the tracker's try on a view whose chain the
        other view's has placed (beside a highlight stripe a corner's normalised CL drops under
        the threshold, and among a whole frame's candidates it falls beyond ``max_candidates``).
        The ROI follows the result."""
        t0 = time.perf_counter()
        img = check_image(gray)
        if not 0.0 < cl_scale <= 1.0:
            raise InputError(f"cl_scale must be in (0, 1], got {cl_scale}")
        s = replace(self.settings, cl_threshold=self.settings.cl_threshold * cl_scale)
        extras: dict[str, float] = {}
        xc = self._chain_in(img, roi, s, extras)
        if xc.corners.shape[0] == 0:
            xc = self._gap_chain(extras)
        return self._result(xc, roi, t0, extras)

    def chains_of_two(self, gray: Any, max_chains: int = 8) -> list[XCorners]:
        """Chains of exactly two corners in the whole image at full scale (uint8 grey or BGR), at
        most ``max_chains``, each sub-pixel as a chain's corners (cvs.corners.chain.find_pairs): a
        sleeve seen so steeply that only the two corners facing the camera pass the X-corner
        test. Texture beside the marker forms such pairs too: the caller tells them apart. The
        ROI state and :meth:`retry_with_gaps` are left as they were."""
        g = to_gray(check_image(gray))
        s = replace(self.settings, min_corners=2)
        cands = find_candidates(g, s, None, self._ws)
        times: dict[str, float] = {}
        out: list[XCorners] = []
        for pair in find_pairs(cands, s, max_chains):
            xc = self._corners(cands, pair, s, 0, 0, times)
            # one corner can leave two candidates (a plateau of CL): the same two corners once
            if xc.corners.shape[0] == 2 and not any(
                    min(np.abs(xc.corners - o.corners).max(), np.abs(xc.corners[::-1] - o.corners).max()) < 1.0
                    for o in out):
                out.append(xc)
        return out

    def detect(self, gray: Any, roi: Roi | None = None, magnify: float = 1.0) -> CornerChain:
        """The marker chain in the whole image or in ``roi`` = (x, y, w, h) [px]; uint8 grey or
        BGR (InputError, a ValueError, otherwise). ``magnify`` >= 1 (with a roi): the box is
        searched enlarged so many times (a small or steeply seen marker whose squares are a few
        pixels wide); corners are returned in the image's own pixels."""
        t0 = time.perf_counter()
        img = check_image(gray)
        s = self.settings
        extras: dict[str, float] = {}
        if not magnify >= 1.0:
            raise InputError(f"magnify must be >= 1, got {magnify}")
        if roi is not None:
            return self._result(self._chain_in(img, roi, s, extras, magnify), roi, t0, extras)
        g = to_gray(img)
        extras["gray_ms"] = 1e3 * (time.perf_counter() - t0)
        if s.coarse_scale > 1 and g.shape[1] >= s.coarse_min_width:
            k = s.coarse_scale
            small = np.asarray(
                cv2.resize(g, (g.shape[1] // k, g.shape[0] // k), interpolation=cv2.INTER_AREA), np.uint8
            )
            coarse = self._chain_in(small, None, scaled_settings(s, k), extras)
            extras["coarse_ms"] = 1e3 * (time.perf_counter() - t0)
            if coarse.corners.shape[0]:
                xc = self._chain_in(g, self._box((coarse.corners + 0.5) * k - 0.5, g.shape), s, extras)
                if xc.corners.shape[0]:
                    return self._result(xc, None, t0, extras)
        return self._result(self._chain_in(g, None, s, extras), None, t0, extras)

    def detect_reduced(self, gray: Any, k: int) -> CornerChain:
        """The marker chain in the whole image reduced ``k`` (>= 2) times by area averaging (its
        top-left part whose sides are multiples of k), searched with the settings scaled to it
        (``scaled_settings``, sub-pixel refinement kept), in the image's own pixels: a sleeve so
        close to the lens, or so far out of focus, that its corners are blurred over several
        pixels fails the X-corner test at full and half scale and can pass it there. Its corners
        are as fine as the reduced image's (a few tenths of a pixel of the full image: fit them
        again at full resolution, as MarkerTracker does). ``retry_with_gaps`` then searches the
        reduced image's candidates."""
        t0 = time.perf_counter()
        g = to_gray(check_image(gray))
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2:
            raise InputError(f"the reduction must be an integer >= 2, got {k!r}")
        k = int(k)
        h, w = (g.shape[0] // k) * k, (g.shape[1] // k) * k
        extras: dict[str, float] = {}
        if h < k or w < k:
            return self._result(XCorners.empty(), None, t0, extras)
        small = np.asarray(cv2.resize(g[:h, :w], (w // k, h // k), interpolation=cv2.INTER_AREA), np.uint8)
        s = replace(scaled_settings(self.settings, k), refine=self.settings.refine)
        t1 = time.perf_counter()
        cands = find_candidates(small, s, None, self._ws)
        chain = find_chain(cands, s)
        extras["reduced_ms"] = 1e3 * (time.perf_counter() - t1)
        self._searched = (cands, s, 0, 0, 1.0 / k)
        return self._result(self._corners(cands, chain, s, 0, 0, extras, 1.0 / k), None, t0, extras)

    def _result(self, xc: XCorners, roi: Roi | None, t0: float, extras: dict[str, float]) -> CornerChain:
        self._last = xc.corners if xc.corners.shape[0] else None
        return CornerChain(
            xc.corners,
            xc.corners_quadric,
            xc.polarity,
            xc.cc,
            xc.cl,
            xc.edges,
            roi=roi,
            time_ms=1e3 * (time.perf_counter() - t0),
            extras=extras,
        )

    def track(self, gray: Any) -> CornerChain:
        """ROI around the previous corners (paper III.A(1)) when there are some and the marker is
        found there, else the whole frame; uint8 grey or BGR."""
        img = check_image(gray)
        box = self.previous_roi((img.shape[0], img.shape[1]))
        if box is not None:
            det = self.detect(img, box)
            if det.corners.shape[0] >= self.settings.min_corners:
                return det
        return self.detect(img)

    def follow(self, corners: Array) -> None:
        """Centre the next ROI search on ``corners`` (N, 2) [px] found otherwise (e.g. by another
        detector in this pair); fewer than two forget the ROI."""
        c = np.asarray(corners, float).reshape(-1, 2)
        self._last = c.copy() if c.shape[0] >= 2 else None

    def previous_roi(self, shape: tuple[int, ...]) -> Roi | None:
        """The box (x, y, w, h) [px] that ``track`` searches first in an image of ``shape`` (rows,
        cols, ...): around the previous corners, with room for one more at either end; None when
        the previous search found no marker."""
        return None if self._last is None else self._box(self._last, (int(shape[0]), int(shape[1])))

    def reset(self) -> None:
        """Forget the ROI (next ``track`` searches the whole frame)."""
        self._last = None

    def _box(self, corners: Array, shape: tuple[int, int]) -> Roi:
        """ROI (x, y, w, h) around chain corners: margin roi_margin_px plus the largest spacing
        (room for one more corner at either end)."""
        gaps = np.hypot(*np.diff(corners, axis=0).T) if corners.shape[0] > 1 else np.zeros(1)
        return _roi_box(corners, self.settings.roi_margin_px + float(np.max(gaps)), shape)
