"""The paper's marker-corner detector (Sec. III.A, eq. 6-10, Fig. 4) and a planar-board helper.

Image frame: raw (distorted) pixels, x right, y down, pixel (0, 0) is the centre of the top-left
pixel; angles in radians measured from +x towards +y. Grey levels are scaled to [0, 1].

Pipeline per image (or region of interest):

1. Corner likelihood (eq. 6). The image is smoothed (Gaussian, ``smooth_sigma``) and 3x3 Sobel
   kernels, normalised to unit gain, give I_x, I_y, I_xx, I_yy, I_xy. The diagonal derivatives
   are formed from them by rotating the derivative directions, u = (x + y)/sqrt2 (0 -> pi/4),
   v = (x - y)/sqrt2 (-pi/4): I_45 = (I_x + I_y)/sqrt2, I_n45 = (I_x - I_y)/sqrt2 (so
   |I_45| + |I_n45| = sqrt2 max(|I_x|, |I_y|)), and the mixed second derivative along the two
   diagonals I_45_45 = d2I/(du dv) = (I_xx - I_yy)/2 (one 3x3 filter). Then
   c_xy = eps^2 |I_xy| - 1.5 eps (|I_45| + |I_n45|), c_45 = eps^2 |I_45_45| - 1.5 eps (|I_x| + |I_y|),
   CL = max(c_xy, c_45), eps = 2.
2. Non-maximum suppression in 5x5; a peak is a candidate when its *normalised* CL, CL divided by
   the local grey-level range of its 11x11 neighbourhood (floored at ``contrast_floor``), is at
   least 0.06: the same threshold then works for dim and bright markers.
3. Edge orientations (eq. 7): gradient angle atan2(I_y, I_x) mod pi weighted by the gradient norm
   in the 11x11 neighbourhood (the paper's 10x10 window, centred on the pixel) -> 32-bin
   histogram -> its two strongest modes, each refined by mean shift over the histogram.
4. Hyperbolic-tangent model (HTM) tanh(u_a/s) tanh(u_b/s) with the two edges, correlated with the
   grey levels of the same neighbourhood (eq. 8, a correlation coefficient); |CC| >= 0.8 is an
   X-corner, sign(CC) its polarity. Polarity convention: edge a is the edge closer to vertical,
   oriented downwards, edge b the other one, oriented to the right; polarity +1 when the sector
   between them (bottom-right for an axis-aligned corner) is bright, i.e. the sign of I_xy there.
5. The marker chain (Fig. 4): candidates in decreasing CL order until one is an X-corner; the
   second corner is the nearest found by moving the window along the four edge directions; then
   the chain grows outward both ways along the local edge direction closest to the last step
   until the searched distance exceeds twice the last spacing. Consecutive corners alternate in
   polarity. Output order: along the chain, first corner = the end with the smaller y.
6. Sub-pixel position: the quadric S = ax^2 + by^2 + cx + dy + exy + f fitted by least squares to
   the 7x7 CL patch and its extremum (eq. 9-10), kept in ``corners_quadric``. Beyond the paper
   (``refine``, default on): a Gauss-Newton fit of the HTM grey-level model itself (centre, both
   edge angles, edge width, grey offset, contrast, linear shading) in a 9x9 window, started at
   the integer CL peak. Measured on rendered 1080p marker images: eq. 10 gives ~0.57 px RMS
   (worse than the integer peak, ~0.43 px: CL is too sharply peaked for a 7x7 quadric), the HTM
   fit ~0.06 px; on OpenCV's real stereo samples it also beats findChessboardCornersSB in
   stereoCalibrate RMS (bench/real_chessboard.py).
7. ROI tracking (paper III.A(1)): ``track`` searches a box around the previous frame's corners
   and the whole frame when there are none or the box loses the marker. Beyond the paper, a cold
   whole-frame search of a large image first runs on a 2x smaller copy (``coarse_scale``) and is
   then redone at full resolution in the box around what it found (falls back to the full-
   resolution whole frame when the small copy shows no chain).

``detect_xcorners`` returns every X-corner of an image (steps 1-4 and 6) and ``assemble_grid``
orders those of a planar chessboard like ``cv2.findChessboardCornersSB``. ROIs are (x, y, w, h)
as in cvs.saddle_corners.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

Array = NDArray[np.float64]
IntArray = NDArray[np.int_]
Roi = tuple[int, int, int, int]
Image = NDArray[np.uint8] | NDArray[np.float32]

_DIFF2 = np.array([[0, -1, 0], [1, 0, 1], [0, -1, 0]], np.float32)  # (Sobel_xx - Sobel_yy) / 4
_NBINS = 32


@dataclass(frozen=True)
class DetectorSettings:
    """Settings of the paper's detector (pixels of the processed image, grey levels in [0, 1]).

    epsilon: eq. 6 weight [px]; smooth_sigma: Gaussian smoothing before the Sobel derivatives
    [px]; nms_size: NMS neighbourhood [px]; cl_threshold: least normalised CL [-];
    contrast_floor: least grey range used to normalise CL [-]; half_window: the 10x10
    neighbourhood as a centred (2 h + 1)^2 window [px]; cc_min: least |CC| of an X-corner [-];
    template_scale: tanh edge width of the HTM [px]; quad_size: side of the quadric patch [px];
    refine: HTM least-squares refinement after eq. 10; refine_radius: its window half-size [px];
    max_step_px: search distance for the second marker corner [px]; stop_ratio: chain search
    limit in units of the last spacing [-]; edge_tol_deg: angle between a step and the found
    corner's edge [deg]; contrast_ratio: least grey range of the next chain corner relative to
    the current one [-]; min_corners: shortest chain [-]; max_seeds: first corners tried [-];
    seed_candidates: strongest candidates that may be a first corner (on rendered frames the
    marker's first corner ranks below 40) [-]; max_candidates: candidates kept [-];
    roi_margin_px: ROI margin around the previous corners, plus their largest spacing [px];
    coarse_scale: downscale of the cold whole-frame search (1: off) [-]; coarse_min_width:
    narrowest image that gets it [px].
    """

    epsilon: float = 2.0
    smooth_sigma: float = 1.5
    nms_size: int = 5
    cl_threshold: float = 0.06
    contrast_floor: float = 0.2
    half_window: int = 5
    cc_min: float = 0.8
    template_scale: float = 1.0
    quad_size: int = 7
    refine: bool = True
    refine_radius: int = 4
    max_step_px: float = 120.0
    stop_ratio: float = 2.0
    edge_tol_deg: float = 20.0
    contrast_ratio: float = 0.4
    min_corners: int = 3
    max_seeds: int = 40
    seed_candidates: int = 300
    max_candidates: int = 3000
    roi_margin_px: int = 25
    coarse_scale: int = 2
    coarse_min_width: int = 1000


@dataclass(frozen=True)
class XCorners:
    """X-corners of one image (raw pixels of the full image).

    corners (N, 2): sub-pixel positions [px] (HTM-refined when enabled); corners_quadric (N, 2):
    eq. 10 positions [px]; polarity (N,) +-1; cc (N,): |CC| of eq. 8 [-]; cl (N,): normalised CL
    [-]; edges (N, 2): angles of edge a (near vertical, pointing down) and edge b (pointing right)
    [rad].
    """

    corners: Array
    corners_quadric: Array
    polarity: IntArray
    cc: Array
    cl: Array
    edges: Array

    @staticmethod
    def empty() -> XCorners:
        """No corner."""
        z = np.zeros((0, 2))
        return XCorners(z, z.copy(), np.zeros(0, int), np.zeros(0), np.zeros(0), z.copy())

    def take(self, idx: IntArray | list[int]) -> XCorners:
        """Subset / reordering by row indices."""
        i = np.asarray(idx, int)
        return XCorners(
            self.corners[i], self.corners_quadric[i], self.polarity[i], self.cc[i], self.cl[i], self.edges[i]
        )


@dataclass(frozen=True)
class CornerChain(XCorners):
    """The marker's corner chain (same fields as XCorners, rows ordered along the chain) plus
    roi: the searched box (x, y, w, h) [px] or None for the whole frame; time_ms: detection time
    [ms]; extras: times of sub-steps [ms] ("coarse_ms": the 2x smaller cold search)."""

    roi: Roi | None = None
    time_ms: float = 0.0
    extras: dict[str, float] = field(default_factory=dict)


# ----------------------------------------------------------------------------- image measures


def _gray(img: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """uint8 grayscale from grayscale, BGR or BGRA; ValueError otherwise."""
    a = np.asarray(img)
    if a.ndim == 3 and a.shape[2] in (3, 4) and a.dtype == np.uint8:
        a = np.asarray(cv2.cvtColor(a, cv2.COLOR_BGR2GRAY if a.shape[2] == 3 else cv2.COLOR_BGRA2GRAY), np.uint8)
    if a.ndim != 2 or a.dtype != np.uint8:
        raise ValueError(f"expected a uint8 grayscale or BGR image, got {a.dtype} {a.shape}")
    return a


@dataclass
class _Level:
    """Everything computed once on one (cropped / scaled) image: raw grey levels (uint8),
    first derivatives, CL, and the candidates (NMS peaks) with their lazily computed X-tests."""

    g: NDArray[np.uint8]
    ix: NDArray[np.float32]
    iy: NDArray[np.float32]
    cl: NDArray[np.float32]
    xs: IntArray
    ys: IntArray
    cln: Array
    rng: Array
    tested: NDArray[np.bool_]
    ok: NDArray[np.bool_]
    cc: Array
    pol: IntArray
    edges: Array


class Workspace:
    """Reusable image buffers: whole-image temporaries are written into these (``dst=``) instead
    of fresh arrays, whose page faults cost more than the filters themselves (measured: CL of a
    960x540 image 8 ms with fresh arrays, 3 ms with reused ones)."""

    def __init__(self) -> None:
        self._buf: dict[str, NDArray[Any]] = {}

    def get(self, name: str, shape: tuple[int, int], dtype: type = np.float32) -> NDArray[Any]:
        """A C-contiguous (h, w) array of ``dtype`` for ``name`` (contents undefined)."""
        n = shape[0] * shape[1]
        b = self._buf.get(name)
        if b is None or b.size < n or b.dtype != dtype:
            b = self._buf[name] = np.empty(max(n, 1), dtype)
        return b[:n].reshape(shape)


def corner_likelihood(
    f: Image, epsilon: float = 2.0, grey_scale: float = 1.0, ws: Workspace | None = None
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """CL of eq. 6 on a smoothed image whose grey levels times ``grey_scale`` lie in [0, 1]
    (uint8: 1/255); returns (CL, I_x, I_y) as float32 (unit-gain Sobel derivatives). With ``ws``
    the results live in its buffers (valid until its next use)."""
    w = ws or Workspace()
    sh = (f.shape[0], f.shape[1])
    ix, iy, ixy, i4545, ax, ay, m, cl = (w.get(k, sh) for k in ("ix", "iy", "ixy", "i45", "ax", "ay", "m", "cl"))
    cv2.Sobel(f, cv2.CV_32F, 1, 0, dst=ix, ksize=3, scale=0.125 * grey_scale)
    cv2.Sobel(f, cv2.CV_32F, 0, 1, dst=iy, ksize=3, scale=0.125 * grey_scale)
    cv2.Sobel(f, cv2.CV_32F, 1, 1, dst=ixy, ksize=3, scale=0.25 * grey_scale)
    cv2.filter2D(f, cv2.CV_32F, _DIFF2 * np.float32(grey_scale), dst=i4545)  # I_xx - I_yy = 2 I_45_45
    np.abs(ix, out=ax)
    np.abs(iy, out=ay)
    np.abs(ixy, out=ixy)
    np.abs(i4545, out=i4545)
    e2, pen = epsilon * epsilon, 1.5 * epsilon
    cv2.max(ax, ay, dst=m)  # |I_45| + |I_n45| = sqrt2 max(|I_x|, |I_y|)
    cv2.addWeighted(ixy, e2, m, -pen * math.sqrt(2.0), 0.0, dst=cl)  # c_xy
    cv2.add(ax, ay, dst=m)
    cv2.addWeighted(i4545, 0.5 * e2, m, -pen, 0.0, dst=ixy)  # c_45
    cv2.max(cl, ixy, dst=cl)
    f32 = np.float32
    return np.asarray(cl, f32), np.asarray(ix, f32), np.asarray(iy, f32)


def _odd(x: float) -> int:
    """Smallest odd integer >= x (Gaussian kernel sizes: +-2 sigma)."""
    k = int(math.ceil(x))
    return k + 1 - k % 2


def _patches(a: Image, xs: IntArray, ys: IntArray, r: int) -> NDArray[np.float32]:
    """(N, 2r+1, 2r+1) float32 windows of ``a`` centred at integer (xs, ys) (all inside)."""
    w = sliding_window_view(a, (2 * r + 1, 2 * r + 1))
    return np.asarray(w[ys - r, xs - r], np.float32)


def _level(
    gray: NDArray[np.uint8], s: DetectorSettings, inner: Roi | None = None, ws: Workspace | None = None
) -> _Level:
    """CL, derivatives and NMS candidates of an image; candidates only inside ``inner`` (x,y,w,h)."""
    ws = ws or Workspace()
    f = gray
    if s.smooth_sigma > 0:
        k = _odd(4 * s.smooth_sigma)  # +-2 sigma
        f = np.asarray(
            cv2.GaussianBlur(gray, (k, k), s.smooth_sigma, dst=ws.get("blur", gray.shape, np.uint8)), np.uint8
        )
    cl, ix, iy = corner_likelihood(f, s.epsilon, 1.0 / 255.0, ws)
    h, w = gray.shape
    r = s.half_window
    border = max(r, s.quad_size // 2) + 2
    x0, y0, x1, y1 = border, border, w - border, h - border
    if inner is not None:
        x0, y0 = max(x0, inner[0]), max(y0, inner[1])
        x1, y1 = min(x1, inner[0] + inner[2]), min(y1, inner[1] + inner[3])
    xs = ys = np.zeros(0, int)
    if x1 > x0 and y1 > y0:
        sub = cl[y0:y1, x0:x1]
        sh = (y1 - y0, x1 - x0)
        dil = cv2.dilate(sub, np.ones((s.nms_size, s.nms_size), np.uint8), dst=ws.get("dil", sh))
        floor = s.cl_threshold * s.contrast_floor
        mask = np.greater_equal(sub, dil, out=ws.get("mask", sh, np.bool_))
        mask &= np.greater(sub, floor, out=ws.get("mask2", sh, np.bool_))
        nz = cv2.findNonZero(mask.view(np.uint8))
        if nz is not None:
            nz = np.asarray(nz).reshape(-1, 2).astype(int)
            xs, ys = nz[:, 0] + x0, nz[:, 1] + y0
    cln = rng = np.zeros(0)
    if xs.size:
        p = _patches(f, xs, ys, r).reshape(xs.size, -1)
        rng = (p.max(axis=1) - p.min(axis=1)) / 255.0
        cln = cl[ys, xs].astype(np.float64) / np.maximum(rng, s.contrast_floor)
        keep = np.flatnonzero(cln >= s.cl_threshold)
        keep = keep[np.argsort(-cln[keep], kind="stable")][: s.max_candidates]
        xs, ys, cln, rng = xs[keep], ys[keep], cln[keep], rng[keep]
    n = xs.size
    return _Level(
        gray,
        ix,
        iy,
        cl,
        xs,
        ys,
        cln,
        rng,
        np.zeros(n, bool),
        np.zeros(n, bool),
        np.zeros(n),
        np.zeros(n, int),
        np.zeros((n, 2)),
    )


def _orientations(ix: NDArray[np.float32], iy: NDArray[np.float32], xs: IntArray, ys: IntArray, r: int) -> Array:
    """Two edge-normal angles (N, 2) in [0, pi) by mean shift on the gradient-weighted orientation
    histogram of each (2r+1)^2 neighbourhood (eq. 7); NaN where there is no second mode."""
    n = xs.size
    gx = _patches(ix, xs, ys, r).reshape(-1)
    gy = _patches(iy, xs, ys, r).reshape(-1)
    wgt, ang = cv2.cartToPolar(gx, gy)  # I_weight and I_angle (in [0, 2 pi))
    b = (np.asarray(ang).ravel() * (_NBINS / np.pi)).astype(int) % _NBINS
    rows = np.repeat(np.arange(n) * _NBINS, (2 * r + 1) ** 2)
    hist = np.bincount(b + rows, np.asarray(wgt).ravel(), n * _NBINS).reshape(n, _NBINS)
    ext = np.concatenate([hist[:, -2:], hist, hist[:, :2]], axis=1)  # circular binomial smoothing
    hs = ext[:, :-4] + 4 * ext[:, 1:-3] + 6 * hist + 4 * ext[:, 3:-1] + ext[:, 4:]
    peak = (hs >= np.roll(hs, 1, 1)) & (hs > np.roll(hs, -1, 1))
    score = np.where(peak, hs, -1.0)
    top = np.argsort(-score, axis=1)[:, :2]
    s2 = np.take_along_axis(score, top, 1)
    modes = (top + 0.5) * (np.pi / _NBINS)
    centres = (np.arange(_NBINS) + 0.5) * (np.pi / _NBINS)
    bw2 = -0.5 / (1.5 * np.pi / _NBINS) ** 2
    for _ in range(2):  # mean shift over the histogram (Gaussian kernel, circular over pi)
        d = np.mod(centres - modes[:, :, None] + np.pi / 2, np.pi) - np.pi / 2
        k = hist[:, None, :] * np.exp(bw2 * d * d)
        modes = modes + (k * d).sum(axis=2) / np.maximum(k.sum(axis=2), 1e-12)
    modes = np.mod(modes, np.pi)
    sep = np.abs(np.mod(modes[:, 0] - modes[:, 1] + np.pi / 2, np.pi) - np.pi / 2)
    bad = (s2[:, 1] <= 0.15 * s2[:, 0]) | (sep < math.radians(20.0))
    modes[bad] = np.nan
    return modes


def _canonical_edges(normals: Array) -> Array:
    """Edge directions (N, 2) from edge-normal angles: a = the edge closer to vertical, pointing
    down (+y); b = the other one, pointing right (+x)."""
    e = normals + np.pi / 2
    vert = np.abs(np.sin(e))
    a_first = vert[:, 0] >= vert[:, 1]
    ea = np.where(a_first, e[:, 0], e[:, 1])
    eb = np.where(a_first, e[:, 1], e[:, 0])
    ea = np.where(np.sin(ea) < 0, ea + np.pi, ea)
    eb = np.where(np.cos(eb) < 0, eb + np.pi, eb)
    return np.column_stack([np.mod(ea + np.pi, 2 * np.pi) - np.pi, np.mod(eb + np.pi, 2 * np.pi) - np.pi])


def _template(edges: Array, r: int, scale: float) -> Array:
    """HTM (N, (2r+1)^2): tanh(u_a/s) tanh(u_b/s), positive between edge a and edge b."""
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
    dx = xx.ravel()[None, :].astype(np.float64)
    dy = yy.ravel()[None, :].astype(np.float64)
    ea, eb = edges[:, :1], edges[:, 1:]
    # normal of a pointing towards b's side and normal of b pointing towards a's side
    na = np.where(np.sin(eb - ea) > 0, 1.0, -1.0)
    nb = -na
    ua = na * (-np.sin(ea) * dx + np.cos(ea) * dy)
    ub = nb * (-np.sin(eb) * dx + np.cos(eb) * dy)
    return np.tanh(ua / scale) * np.tanh(ub / scale)


def _xtest(lv: _Level, idx: IntArray, s: DetectorSettings) -> None:
    """Edge orientations + HTM correlation for candidates ``idx`` (in place on ``lv``)."""
    idx = idx[~lv.tested[idx]]
    if idx.size == 0:
        return
    xs, ys, r = lv.xs[idx], lv.ys[idx], s.half_window
    normals = _orientations(lv.ix, lv.iy, xs, ys, r)
    good = np.all(np.isfinite(normals), axis=1)
    edges = _canonical_edges(np.where(np.isfinite(normals), normals, 0.0))
    g = _patches(lv.g, xs, ys, r).reshape(xs.size, -1).astype(np.float64)
    t = _template(edges, r, s.template_scale)
    g = g - g.mean(axis=1, keepdims=True)
    t = t - t.mean(axis=1, keepdims=True)
    cc = (g * t).sum(axis=1) / np.maximum(np.sqrt((g * g).sum(axis=1) * (t * t).sum(axis=1)), 1e-12)
    lv.tested[idx] = True
    lv.cc[idx] = np.abs(cc)
    lv.pol[idx] = np.where(cc >= 0, 1, -1)
    lv.edges[idx] = edges
    lv.ok[idx] = good & (np.abs(cc) >= s.cc_min)


# ----------------------------------------------------------------------------- sub-pixel


def _quadric_pinv(size: int) -> Array:
    r = size // 2
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    x, y = xx.ravel(), yy.ravel()
    return np.linalg.pinv(np.column_stack([x * x, y * y, x, y, x * y, np.ones_like(x)]))


_QPINV: dict[int, Array] = {}


def quadric_subpixel(cl: NDArray[np.float32], xs: IntArray, ys: IntArray, size: int = 7) -> Array:
    """Eq. 9-10: extremum of the quadric fitted to the size x size CL patch around each integer
    peak -> (N, 2) sub-pixel positions [px]; the peak itself where the fit has no maximum within
    1 px."""
    if size not in _QPINV:
        _QPINV[size] = _quadric_pinv(size)
    p = _patches(cl, xs, ys, size // 2).reshape(xs.size, -1).astype(np.float64)
    a, b, c, d, e, _ = (p @ _QPINV[size].T).T
    den = 4 * a * b - e * e
    with np.errstate(divide="ignore", invalid="ignore"):
        xo = (d * e - 2 * b * c) / den
        yo = (c * e - 2 * a * d) / den
    ok = (den > 0) & (a < 0) & (np.abs(xo) <= 1.0) & (np.abs(yo) <= 1.0)
    out = np.column_stack([xs, ys]).astype(np.float64)
    out[ok, 0] += xo[ok]
    out[ok, 1] += yo[ok]
    return out


def htm_refine(
    img: Image, pts: Array, edges: Array, r: int = 4, sigma_w: Array | float = 4.0, iters: int = 3
) -> tuple[Array, Array, NDArray[np.bool_]]:
    """Least-squares fit of the HTM grey-level model b + a tanh(u_a/s) tanh(u_b/s) + g.(p - c) to
    the (2r+1)^2 patch of ``img`` around each point (Gaussian weights sigma_w [px]): Gauss-Newton
    on the centre c, both edge angles (as in XCorners.edges), s, a, b and g, started from the
    linear least-squares a, b, g at the given centre and edges (3 steps converge to ~1e-3 px).
    Returns points (N, 2) [px], edge angles (N, 2) [rad] and ok (N,): False (input returned) where
    the fit fails or moves more than 1.5 px."""
    n = pts.shape[0]
    if n == 0:
        return pts.copy(), edges.copy(), np.zeros(0, bool)
    h, w = img.shape
    ci = np.rint(pts).astype(int)
    inside = (ci[:, 0] >= r) & (ci[:, 1] >= r) & (ci[:, 0] < w - r) & (ci[:, 1] < h - r)
    ci = np.clip(ci, r, [w - r - 1, h - r - 1])
    P = _patches(img, ci[:, 0], ci[:, 1], r).reshape(n, -1).astype(np.float64)
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
    X = xx.ravel()[None, :] + ci[:, :1].astype(np.float64)
    Y = yy.ravel()[None, :] + ci[:, 1:].astype(np.float64)
    sw = np.broadcast_to(np.asarray(sigma_w, np.float64), (n,))[:, None]
    W = np.exp(-0.5 * ((X - pts[:, :1]) ** 2 + (Y - pts[:, 1:]) ** 2) / sw**2)
    th = np.column_stack([pts, edges, np.ones(n), np.zeros((n, 4))])  # cx cy ea eb s | a b gx gy
    eye = np.eye(9)
    for it in range(iters + 1):
        dx, dy = X - th[:, 0:1], Y - th[:, 1:2]
        ca, sa_, cb, sb = np.cos(th[:, 2:3]), np.sin(th[:, 2:3]), np.cos(th[:, 3:4]), np.sin(th[:, 3:4])
        sg = np.where(cb * sa_ - sb * ca < 0, 1.0, -1.0)  # sign of sin(eb - ea)
        ua = sg * (ca * dy - sa_ * dx)  # normal of a towards b
        ub = -sg * (cb * dy - sb * dx)  # normal of b towards a
        s = th[:, 4:5]
        ta, tb = np.tanh(ua / s), np.tanh(ub / s)
        T = ta * tb
        if it == 0:  # linear start for a, b, g
            B = np.stack([T, np.ones_like(T), dx, dy], axis=2)
            BW = B * W[:, :, None]
            th[:, 5:] = np.linalg.solve(
                np.einsum("npi,npj->nij", BW, B) + 1e-9 * np.eye(4), np.einsum("npi,np->ni", BW, P)[:, :, None]
            )[:, :, 0]
            continue
        amp = th[:, 5:6]
        res = P - (amp * T + th[:, 6:7] + th[:, 7:8] * dx + th[:, 8:9] * dy)
        dma = amp * (1 - ta * ta) / s * tb  # d model / d u_a
        dmb = amp * (1 - tb * tb) / s * ta
        J = np.stack(
            [
                dma * sg * sa_ - dmb * sg * sb - th[:, 7:8],  # d/dcx: d ua/dcx = sg sa
                -dma * sg * ca + dmb * sg * cb - th[:, 8:9],
                -dma * sg * (sa_ * dy + ca * dx),  # d ua / d ea
                dmb * sg * (sb * dy + cb * dx),
                -(dma * ua + dmb * ub) / s,
                T,
                np.ones_like(T),
                dx,
                dy,
            ],
            axis=2,
        )
        JW = J * W[:, :, None]
        H = np.einsum("npi,npj->nij", JW, J)
        H += (1e-6 * H.diagonal(axis1=1, axis2=2)[:, :, None] + 1e-12) * eye
        try:
            step = np.linalg.solve(H, np.einsum("npi,np->ni", JW, res)[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            break
        step[:, :2] = np.clip(step[:, :2], -0.5, 0.5)
        step[:, 2:4] = np.clip(step[:, 2:4], -0.2, 0.2)
        th += step
        th[:, 4] = np.clip(th[:, 4], 0.3, 4.0)
        if np.all(np.abs(step[:, :2]) < 2e-3):
            break
    ok = inside & np.all(np.isfinite(th), axis=1) & (np.hypot(*(th[:, :2] - pts).T) <= 1.5)
    out, e = pts.copy(), edges.copy()
    out[ok], e[ok] = th[ok, :2], th[ok, 2:4]
    return out, e, ok


def _subpixel(lv: _Level, idx: IntArray, s: DetectorSettings, spacing: Array) -> tuple[Array, Array, Array]:
    """(refined, quadric, edges) of candidates ``idx`` in level pixels; ``spacing`` [px]: distance
    to the nearest other corner (sets the HTM fit's Gaussian window, sigma = 0.12 spacing in
    [1.5, 4] px). The HTM fit starts from the integer CL peak: on rendered marker corners the 7x7
    quadric of eq. 9-10 is often further from the corner than the peak itself (CL is too sharply
    peaked for a 7x7 quadric)."""
    xs, ys = lv.xs[idx], lv.ys[idx]
    q = quadric_subpixel(lv.cl, xs, ys, s.quad_size)
    edges = lv.edges[idx]
    if not s.refine or idx.size == 0:
        return q, q.copy(), edges
    start = np.column_stack([xs, ys]).astype(np.float64)
    ref, e, ok = htm_refine(lv.g, start, edges, s.refine_radius, np.clip(0.12 * spacing, 1.5, 4.0))
    ref[~ok] = q[~ok]
    return ref, q, e


# ----------------------------------------------------------------------------- chain (Fig. 4)


def _unit(a: float) -> Array:
    return np.array([math.cos(a), math.sin(a)])


def _search(lv: _Level, cur: int, d: Array, max_dist: float, used: set[int], s: DetectorSettings) -> int:
    """Move the window from corner ``cur`` along ``d`` (half-window steps) until ``max_dist``:
    the first window whose CL maximum is an X-corner of the other polarity with an edge along the
    step and a grey-level range at least ``contrast_ratio`` times that of ``cur`` (rejects X-like
    texture next to the marker). The window is the paper's 10x10 square, widened across the step
    to 20% of the distance so that a curved corner circle stays inside it. Returns the candidate
    index or -1."""
    p = np.array([lv.xs[cur], lv.ys[cur]], float)
    pol = -int(lv.pol[cur])
    min_rng = s.contrast_ratio * float(lv.rng[cur])
    r = s.half_window
    rel = np.column_stack([lv.xs, lv.ys]).astype(np.float64) - p
    along = rel @ d
    across = np.abs(rel @ np.array([-d[1], d[0]]))
    band = np.flatnonzero((along > 1.0) & (along <= max_dist + r) & (across <= np.maximum(r, 0.2 * (along + r))))
    if band.size == 0:
        return -1
    _xtest(lv, band, s)  # only the candidates some window will see
    cands = sorted(zip(along[band].tolist(), across[band].tolist(), band.tolist()))
    cos_tol = math.cos(math.radians(s.edge_tol_deg))
    t = float(r + 1)
    while t <= max_dist + 1e-9:
        lat = max(r, 0.2 * t)
        inw = [k for al, ac, k in cands if abs(al - t) <= r and ac <= lat]
        t += r
        if not inw:
            continue
        k = max(inw, key=lambda j: lv.cln[j])  # the window's CL maximum
        if k in used or not lv.ok[k] or lv.pol[k] != pol or lv.rng[k] < min_rng:
            continue
        step = np.array([lv.xs[k], lv.ys[k]], float) - p
        dist = float(np.hypot(*step))
        if dist < 2.0 or dist > max_dist + r:
            continue
        u = step / dist
        if max(abs(float(_unit(a) @ u)) for a in lv.edges[k]) < cos_tol:
            continue
        return k
    return -1


def _best_edge(edges: Array, u: Array) -> Array:
    """The edge direction (of four) closest to unit vector ``u``."""
    cands = [_unit(a) for a in edges]
    dots = [float(c @ u) for c in cands]
    j = int(np.argmax(np.abs(dots)))
    return cands[j] * (1.0 if dots[j] >= 0 else -1.0)


def _turned(d_cur: Array, d_prev: Array) -> Array:
    """``d_cur`` turned on by half the angle from ``d_prev`` to ``d_cur`` (chord of an arc)."""
    a = math.atan2(d_cur[1], d_cur[0])
    da = math.atan2(d_prev[0] * d_cur[1] - d_prev[1] * d_cur[0], float(d_prev @ d_cur))
    return _unit(a + 0.5 * da)


def _grow(lv: _Level, seed: int, s: DetectorSettings) -> list[int]:
    """The chain through ``seed`` (Fig. 4), ordered along the chain. The next corner is searched
    along the current corner's edge closest to the last step, turned by half the change of that
    edge since the previous corner (the corner circle's image is curved)."""
    p = lambda k: np.array([lv.xs[k], lv.ys[k]], float)  # noqa: E731
    used = {seed}
    best, best_d = -1, math.inf
    for a in lv.edges[seed]:
        for sign in (1.0, -1.0):
            k = _search(lv, seed, sign * _unit(a), s.max_step_px, used, s)
            if k >= 0 and np.hypot(*(p(k) - p(seed))) < best_d:
                best, best_d = k, float(np.hypot(*(p(k) - p(seed))))
    if best < 0:
        return [seed]
    chain = [seed, best]
    used.add(best)
    for forward in (True, False):
        while len(chain) < 64:
            cur, prev = (chain[-1], chain[-2]) if forward else (chain[0], chain[1])
            step = p(cur) - p(prev)
            dist = float(np.hypot(*step))
            u = step / dist
            d = _turned(_best_edge(lv.edges[cur], u), _best_edge(lv.edges[prev], u))
            k = _search(lv, cur, d, s.stop_ratio * dist, used, s)
            if k < 0:
                break
            used.add(k)
            if forward:
                chain.append(k)
            else:
                chain.insert(0, k)
    return chain


def _find_chain(lv: _Level, s: DetectorSettings) -> list[int]:
    """Seeds in decreasing (normalised) CL order until a chain of ``min_corners`` is found."""
    n = min(lv.xs.size, s.seed_candidates)
    seeds = 0
    lo = 0
    while lo < n:
        hi = n if n <= 400 else min(n, lo + (16 if lo == 0 else 64))  # a ROI: one batch
        batch = np.arange(lo, hi)
        lo = hi
        _xtest(lv, batch, s)
        for k in batch[lv.ok[batch]]:
            chain = _grow(lv, int(k), s)
            if len(chain) >= s.min_corners:
                return chain
            seeds += 1
            if seeds >= s.max_seeds:
                return []
    return []


# ----------------------------------------------------------------------------- public API


def _roi_box(pts: Array, margin: float, shape: tuple[int, int]) -> Roi:
    h, w = shape
    lo = np.maximum(np.floor(pts.min(axis=0) - margin), 0).astype(int)
    hi = np.minimum(np.ceil(pts.max(axis=0) + margin), [w - 1, h - 1]).astype(int)
    return int(lo[0]), int(lo[1]), int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)


def _crop(gray: NDArray[np.uint8], roi: Roi, pad: int) -> tuple[NDArray[np.uint8], int, int, Roi]:
    """Crop ``roi`` plus ``pad`` (so filters inside the roi equal the whole-frame ones)."""
    h, w = gray.shape
    x, y, rw, rh = roi
    x0, y0 = max(x - pad, 0), max(y - pad, 0)
    x1, y1 = min(x + rw + pad, w), min(y + rh + pad, h)
    return gray[y0:y1, x0:x1], x0, y0, (x - x0, y - y0, rw, rh)


BOARD_SETTINGS = DetectorSettings(cl_threshold=0.03)
"""detect_xcorners' default: a planar board is seen at any in-plane rotation, and eq. 6's two
fixed orientations (0 and 45 degrees) give corners rotated by ~22 degrees a weaker CL (on OpenCV's
stereo samples 6 of 1404 corners have a normalised CL between 0.049 and 0.06); the HTM test still
decides."""


def detect_xcorners(gray: NDArray[np.uint8], settings: DetectorSettings | None = None) -> XCorners:
    """Every X-corner of a grayscale (or BGR) uint8 image: CL, NMS, HTM test and sub-pixel fit;
    rows in decreasing normalised CL. Default settings: ``BOARD_SETTINGS``."""
    s = settings or BOARD_SETTINGS
    lv = _level(_gray(gray), s)
    idx = np.arange(lv.xs.size)
    _xtest(lv, idx, s)
    idx = idx[lv.ok[idx]]
    if idx.size == 0:
        return XCorners.empty()
    pts = np.column_stack([lv.xs[idx], lv.ys[idx]]).astype(np.float64)
    d = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1)) + np.diag(np.full(idx.size, np.inf))
    ref, q, e = _subpixel(lv, idx, s, d.min(axis=1))
    return XCorners(ref, q, lv.pol[idx].copy(), lv.cc[idx].copy(), lv.cln[idx].copy(), e)


class MarkerCornerDetector:
    """The paper's marker-corner detector with ROI tracking (same interface as
    cvs.saddle_corners.SaddleCornerDetector: ``detect``, ``track``, ``reset``)."""

    def __init__(self, settings: DetectorSettings | None = None) -> None:
        self.settings = settings or DetectorSettings()
        self._last: Array | None = None
        self._ws = Workspace()
        cv2.setNumThreads(1)

    def _chain_in(self, g: NDArray[np.uint8], roi: Roi | None, s: DetectorSettings) -> XCorners:
        """Chain in the whole image or in roi (x, y, w, h), full-image pixels."""
        x0 = y0 = 0
        inner = None
        if roi is not None:
            pad = int(math.ceil(3 * s.smooth_sigma)) + s.half_window + s.quad_size + 2
            g, x0, y0, inner = _crop(g, roi, pad)
        lv = _level(g, s, inner, self._ws)
        chain = _find_chain(lv, s)
        if len(chain) < s.min_corners:
            return XCorners.empty()
        idx = np.array(chain, int)
        pts = np.column_stack([lv.xs[idx], lv.ys[idx]]).astype(np.float64)
        gaps = np.hypot(*np.diff(pts, axis=0).T)
        spacing = np.minimum(np.r_[gaps, np.inf], np.r_[np.inf, gaps])
        spacing[[0, -1]] *= 0.6  # foreshortening: an unseen next corner is closer than the last step
        ref, q, e = _subpixel(lv, idx, s, spacing)
        off = np.array([x0, y0], float)
        xc = XCorners(ref + off, q + off, lv.pol[idx].copy(), lv.cc[idx].copy(), lv.cln[idx].copy(), e)
        return xc if xc.corners[0, 1] <= xc.corners[-1, 1] else xc.take(np.arange(idx.size)[::-1])

    def detect(self, gray: NDArray[np.uint8], roi: Roi | None = None) -> CornerChain:
        """The marker chain in the whole image or in ``roi`` = (x, y, w, h) [px]; uint8 gray/BGR."""
        t0 = time.perf_counter()
        g = _gray(gray)
        s = self.settings
        extras: dict[str, float] = {}
        if roi is None and s.coarse_scale > 1 and g.shape[1] >= s.coarse_min_width:
            k = s.coarse_scale
            small = np.asarray(
                cv2.resize(g, (g.shape[1] // k, g.shape[0] // k), interpolation=cv2.INTER_AREA), np.uint8
            )
            sc = _scaled(s, k)
            coarse = self._chain_in(small, None, sc)
            extras["coarse_ms"] = 1e3 * (time.perf_counter() - t0)
            if coarse.corners.shape[0]:
                xc = self._chain_in(g, self._box((coarse.corners + 0.5) * k - 0.5, g.shape), s)
                if xc.corners.shape[0]:
                    return self._result(xc, None, t0, extras)
        xc = self._chain_in(g, roi, s)
        return self._result(xc, roi, t0, extras)

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

    def track(self, gray: NDArray[np.uint8]) -> CornerChain:
        """ROI around the previous corners (paper III.A(1)) when there are some and the marker is
        found there, else the whole frame."""
        g = _gray(gray)
        if self._last is not None:
            det = self.detect(g, self._box(self._last, g.shape))
            if det.corners.shape[0] >= self.settings.min_corners:
                return det
        return self.detect(g)

    def reset(self) -> None:
        """Forget the ROI (next ``track`` searches the whole frame)."""
        self._last = None

    def _box(self, corners: Array, shape: tuple[int, int]) -> Roi:
        """ROI (x, y, w, h) around chain corners: margin roi_margin_px plus the largest spacing
        (room for one more corner at either end)."""
        gaps = np.hypot(*np.diff(corners, axis=0).T) if corners.shape[0] > 1 else np.zeros(1)
        return _roi_box(corners, self.settings.roi_margin_px + float(np.max(gaps)), shape)


def _scaled(s: DetectorSettings, k: int) -> DetectorSettings:
    """Settings for an image k times smaller (distances shrink, windows stay)."""
    return replace(s, smooth_sigma=max(s.smooth_sigma / k, 1.0), max_step_px=s.max_step_px / k, refine=False)


# ----------------------------------------------------------------------------- planar boards


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
        sm = cv2.GaussianBlur(_gray(gray), (5, 5), 0)
        h, w = sm.shape

        def grey(p: Array) -> float:
            x, y = int(np.clip(round(p[0]), 0, w - 1)), int(np.clip(round(p[1]), 0, h - 1))
            return float(sm[y, x])

        p0 = grid[0, 0]
        flip = grey(p0 + 0.35 * (a + b)) < grey(p0 + 0.35 * (a - b))
    else:
        flip = float(grid[-1, -1].sum()) < float(grid[0, 0].sum())
    return grid[::-1, ::-1] if flip else grid
