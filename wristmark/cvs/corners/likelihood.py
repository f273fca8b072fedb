"""Corner likelihood (paper eq. 6) and its non-maximum-suppression candidates (steps 1-2 of
cvs.corners.detector).

CL from unit-gain 3x3 Sobel derivatives of the smoothed image: I_45 = (I_x + I_y)/sqrt2,
I_n45 = (I_x - I_y)/sqrt2 (so |I_45| + |I_n45| = sqrt2 max(|I_x|, |I_y|)) and the mixed second
derivative along the two diagonals I_45_45 = (I_xx - I_yy)/2; then
c_xy = eps^2 |I_xy| - 1.5 eps (|I_45| + |I_n45|), c_45 = eps^2 |I_45_45| - 1.5 eps (|I_x| + |I_y|),
CL = max(c_xy, c_45). Candidates are the 5x5 NMS peaks whose CL divided by the grey-level range
of their 11x11 neighbourhood (floored) passes ``cl_threshold``, strongest first.

Both kernels are numba-compiled single passes (measured on a 250x380 marker ROI: CL 0.09 ms
against 0.34 ms for the eleven OpenCV/numpy calls it replaces, with the same float32 results;
NMS + contrast 0.05 ms against 0.26 ms for dilate, compare, findNonZero and the patch ranges).
Image frame as in cvs.corners.xcorners; borders of the derivatives are reflected (OpenCV's
BORDER_REFLECT_101).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.corners.xcorners import Array, DetectorSettings, IntArray, Roi

Image = NDArray[np.uint8] | NDArray[np.float32]


class Workspace:
    """Reusable image buffers: whole-image temporaries are written into these instead of fresh
    arrays, whose page faults cost more than the filters themselves (measured: CL of a 960x540
    image 8 ms with fresh arrays, 3 ms with reused ones)."""

    def __init__(self) -> None:
        self._buf: dict[str, NDArray[Any]] = {}

    def get(self, name: str, shape: tuple[int, int], dtype: type = np.float32) -> NDArray[Any]:
        """A C-contiguous (h, w) array of ``dtype`` for ``name`` (contents undefined)."""
        n = shape[0] * shape[1]
        b = self._buf.get(name)
        if b is None or b.size < n or b.dtype != dtype:
            b = self._buf[name] = np.empty(max(n, 1), dtype)
        return b[:n].reshape(shape)


@numba.njit(cache=True, nogil=True)
def _reflect(i: int, n: int) -> int:
    """BORDER_REFLECT_101 index."""
    if n == 1:
        return 0
    if i < 0:
        return -i
    if i >= n:
        return 2 * n - 2 - i
    return i


@numba.njit(cache=True, nogil=True, fastmath={"contract"})
def _fused_rows(r0: Any, r1: Any, r2: Any, s1: Any, s2: Any, sm0: Any, sm2: Any, gx: Any) -> None:  # pragma: no cover
    """Along padded rows r0, r1, r2 (above, at, below): the [1 2 1] s1 smoothing of r0 and r2
    and I_x, as fused multiply-adds (the ``contract`` flag lets LLVM emit FMA instructions)."""
    for x in range(sm0.shape[0]):
        sm0[x] = r0[x + 2] * s1 + (r0[x + 1] * s2 + r0[x] * s1)
        sm2[x] = r2[x + 2] * s1 + (r2[x + 1] * s2 + r2[x] * s1)
        gx[x] = ((r0[x + 2] - r0[x]) + (r2[x + 2] - r2[x])) * s1 + (r1[x + 2] - r1[x]) * s2


@numba.njit(cache=True, nogil=True)
def _cl_kernel(f: Any, epsilon: float, grey_scale: float, cl: Any, ix: Any, iy: Any) -> None:  # pragma: no cover
    """CL, I_x, I_y (float32) of image f in one pass over buffered rows with reflected ends.

    The float32 operations are those of OpenCV 5's separable 3x3 Sobel (differences along the
    derivative, then the scaled [1 2 1] smoothing as fused multiply-adds; along a row the last
    width mod 32 columns get plain multiply-adds, which its AVX2 row filter leaves to scalar
    code), its 3x3 filter2D and addWeighted, in the same order: on this machine the results
    equal the cv2 calls they replace bit for bit, so the detector's output did not change with
    the rewrite (elsewhere they may differ in the last bit)."""
    h, w = f.shape
    f32 = np.float32
    s1 = f32(0.125 * grey_scale)  # unit-gain first derivative: [1 2 1] / 8 smoothing
    s2 = f32(2.0) * s1
    s11 = f32(0.25 * grey_scale)  # unit-gain I_xy
    k2 = f32(grey_scale)  # (I_xx - I_yy) / 4 per grey level -> I_xx - I_yy = 2 I_45_45
    e2 = f32(epsilon * epsilon)
    half_e2 = f32(0.5 * epsilon * epsilon)
    pen = f32(-1.5 * epsilon)
    pen_diag = f32(-1.5 * epsilon * math.sqrt(2.0))
    tail = (w // 32) * 32
    r0, r1, r2 = np.empty(w + 2, f32), np.empty(w + 2, f32), np.empty(w + 2, f32)
    sm0, sm2, gxr = np.empty(w, f32), np.empty(w, f32), np.empty(w, f32)
    for y in range(h):
        ym, yp = _reflect(y - 1, h), _reflect(y + 1, h)
        for x in range(w):
            r0[x + 1] = f[ym, x]
            r1[x + 1] = f[y, x]
            r2[x + 1] = f[yp, x]
        xl, xr = _reflect(-1, w), _reflect(w, w)
        r0[0], r1[0], r2[0] = f[ym, xl], f[y, xl], f[yp, xl]
        r0[w + 1], r1[w + 1], r2[w + 1] = f[ym, xr], f[y, xr], f[yp, xr]
        _fused_rows(r0, r1, r2, s1, s2, sm0, sm2, gxr)
        for x in range(tail, w):
            sm0[x] = (r0[x] * s1 + r0[x + 1] * s2) + r0[x + 2] * s1
            sm2[x] = (r2[x] * s1 + r2[x + 1] * s2) + r2[x + 2] * s1
        for x in range(w):
            gx, gy = gxr[x], sm2[x] - sm0[x]
            gxy = ((r2[x + 2] - r2[x]) - (r0[x + 2] - r0[x])) * s11
            d45 = (((-r0[x + 1]) * k2 + r1[x] * k2) + r1[x + 2] * k2) - r2[x + 1] * k2
            ax, ay = abs(gx), abs(gy)
            c_xy = abs(gxy) * e2 + max(ax, ay) * pen_diag
            c_45 = abs(d45) * half_e2 + (ax + ay) * pen
            cl[y, x] = max(c_xy, c_45)
            ix[y, x] = gx
            iy[y, x] = gy


def corner_likelihood(
    f: Image, epsilon: float = 2.0, grey_scale: float = 1.0, ws: Workspace | None = None
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """CL of eq. 6 on a smoothed image whose grey levels times ``grey_scale`` lie in [0, 1]
    (uint8: 1/255); returns (CL, I_x, I_y) as float32 (unit-gain Sobel derivatives). With ``ws``
    the results live in its buffers (valid until its next use)."""
    a = np.asarray(f)
    if a.ndim != 2 or a.size == 0:
        raise ValueError(f"corner_likelihood needs a non-empty 2-D image, got shape {a.shape}")
    a = np.ascontiguousarray(a if a.dtype == np.uint8 else a.astype(np.float32, copy=False))
    w = ws or Workspace()
    sh = (a.shape[0], a.shape[1])
    cl, ix, iy = w.get("cl", sh), w.get("ix", sh), w.get("iy", sh)
    _cl_kernel(a, float(epsilon), float(grey_scale), cl, ix, iy)
    return cl, ix, iy


@numba.njit(cache=True, nogil=True)
def _any_above(cl: Any, y: int, xa: int, xb: int, floor: Any) -> bool:  # pragma: no cover
    """Whether any of cl[y, xa:xb] exceeds floor (a branch-free, vectorised scan)."""
    m = False
    for x in range(xa, xb):
        m |= cl[y, x] > floor
    return m


@numba.njit(cache=True, nogil=True)
def _is_peak(cl: Any, x: int, y: int, xa: int, xb: int, ya: int, yb: int) -> bool:  # pragma: no cover
    """cl[y, x] >= every value of cl[ya:yb, xa:xb] (a grey dilation's maximum; ties kept)."""
    v = cl[y, x]
    for yy in range(ya, yb):
        for xx in range(xa, xb):
            if cl[yy, xx] > v:
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _grey_range(f: Any, x: int, y: int, r: int) -> Any:  # pragma: no cover
    """float32 (max - min) / 255 of f over the (2r+1)^2 window at (x, y), as numpy computes it."""
    f32 = np.float32
    lo = hi = f32(f[y, x])
    for yy in range(y - r, y + r + 1):
        for xx in range(x - r, x + r + 1):
            g = f32(f[yy, xx])
            lo = min(lo, g)
            hi = max(hi, g)
    return f32((hi - lo) / f32(255.0))


@numba.njit(cache=True, nogil=True)
def _nms_kernel(
    cl: Any, f: Any, x0: int, y0: int, x1: int, y1: int, nms_size: int, floor: float, r: int,
    contrast_floor: float, cl_threshold: float,
) -> tuple[Any, Any, Any, Any]:  # pragma: no cover
    """Row-major NMS peaks of cl in [x0, x1) x [y0, y1) (a grey dilation by an nms_size square
    clipped to that box, ties kept, CL > floor) with normalised CL >= cl_threshold: (xs, ys,
    normalised CL, grey range of f). Comparisons in float32, as numpy's on float32 images."""
    cap = 256
    xs, ys = np.empty(cap, np.int64), np.empty(cap, np.int64)
    cln, rng = np.empty(cap, np.float64), np.empty(cap, np.float32)
    n = 0
    cf, fl = np.float32(contrast_floor), np.float32(floor)
    lo_off, hi_off = nms_size // 2, nms_size - 1 - nms_size // 2  # cv2.dilate's centred anchor
    chunk = 16  # columns scanned at once for a CL above the floor (most have none)
    for y in range(y0, y1):
        if not _any_above(cl, y, x0, x1, fl):
            continue
        ya, yb = max(y - lo_off, y0), min(y + hi_off + 1, y1)
        for xc in range(x0, x1, chunk):
            if not _any_above(cl, y, xc, min(xc + chunk, x1), fl):
                continue
            for x in range(xc, min(xc + chunk, x1)):
                if not cl[y, x] > fl or not _is_peak(cl, x, y, max(x - lo_off, x0), min(x + hi_off + 1, x1), ya, yb):
                    continue
                rg = _grey_range(f, x, y, r)
                c = np.float64(cl[y, x]) / np.float64(max(rg, cf))
                if not c >= cl_threshold:
                    continue
                if n == cap:  # grow the outputs
                    cap *= 2
                    xs2, ys2 = np.empty(cap, np.int64), np.empty(cap, np.int64)
                    cln2, rng2 = np.empty(cap, np.float64), np.empty(cap, np.float32)
                    xs2[:n], ys2[:n], cln2[:n], rng2[:n] = xs, ys, cln, rng
                    xs, ys, cln, rng = xs2, ys2, cln2, rng2
                xs[n], ys[n], cln[n], rng[n] = x, y, c, rg
                n += 1
    return xs[:n], ys[:n], cln[:n], rng[:n]


@dataclass
class CornerCandidates:
    """Everything computed once on one (cropped / scaled) image: raw grey levels (uint8), first
    derivatives, CL, and the candidates (NMS peaks, strongest normalised CL first) with their
    lazily computed X-corner tests (cvs.corners.xcorner_test): tested, ok, |CC|, polarity, edges."""

    gray: NDArray[np.uint8]
    ix: NDArray[np.float32]
    iy: NDArray[np.float32]
    cl: NDArray[np.float32]
    xs: IntArray
    ys: IntArray
    cln: Array
    rng: NDArray[np.float32]
    tested: NDArray[np.bool_]
    ok: NDArray[np.bool_]
    cc: Array
    pol: IntArray
    edges: Array

    def points(self, idx: IntArray) -> Array:
        """(N, 2) integer pixel positions of candidates ``idx`` as floats [px]."""
        return np.column_stack([self.xs[idx], self.ys[idx]]).astype(np.float64)


def _odd(x: float) -> int:
    """Smallest odd integer >= x (Gaussian kernel sizes: +-2 sigma)."""
    k = int(math.ceil(x))
    return k + 1 - k % 2


def find_candidates(
    gray: NDArray[np.uint8], s: DetectorSettings, inner: Roi | None = None, ws: Workspace | None = None
) -> CornerCandidates:
    """Smoothing, CL, derivatives and NMS candidates of a uint8 image; candidates only inside
    ``inner`` (x, y, w, h) [px] and far enough from the border for every window."""
    ws = ws or Workspace()
    g = np.ascontiguousarray(gray)
    if not g.flags.writeable:  # one compiled specialisation for all inputs (numba types read-only apart)
        g = g.copy()
    f = g
    if s.smooth_sigma > 0:
        k = _odd(4 * s.smooth_sigma)  # +-2 sigma
        f = np.asarray(cv2.GaussianBlur(g, (k, k), s.smooth_sigma, dst=ws.get("blur", g.shape, np.uint8)), np.uint8)
    cl, ix, iy = corner_likelihood(f, s.epsilon, 1.0 / 255.0, ws)
    h, w = g.shape
    r = s.half_window
    border = max(r, s.quad_size // 2) + 2
    x0, y0, x1, y1 = border, border, w - border, h - border
    if inner is not None:
        x0, y0 = max(x0, inner[0]), max(y0, inner[1])
        x1, y1 = min(x1, inner[0] + inner[2]), min(y1, inner[1] + inner[3])
    if x1 > x0 and y1 > y0:
        xs, ys, cln, rng = _nms_kernel(
            cl, f, x0, y0, x1, y1, s.nms_size, s.cl_threshold * s.contrast_floor, r,
            s.contrast_floor, s.cl_threshold,
        )
        keep = np.argsort(-cln, kind="stable")[: s.max_candidates]
        xs, ys, cln, rng = xs[keep], ys[keep], cln[keep], rng[keep]
    else:
        xs, ys, cln, rng = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.float32)
    n = xs.size
    return CornerCandidates(
        g, ix, iy, cl, xs, ys, cln, rng, np.zeros(n, bool), np.zeros(n, bool), np.zeros(n), np.zeros(n, np.int64),
        np.zeros((n, 2)),
    )
