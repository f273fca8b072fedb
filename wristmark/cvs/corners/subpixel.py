"""Sub-pixel corner positions (step 6 of cvs.corners.detector).

- The paper's quadric (eq. 9-10): S = ax^2 + by^2 + cx + dy + exy + f fitted by least squares to
  the 7x7 CL patch around the integer peak, and its extremum.
- Beyond the paper: a Gauss-Newton fit of the HTM grey-level model itself,
  b + a tanh(u_a/s) tanh(u_b/s) + g.(p - c), on the raw grey levels of a (2r+1)^2 window with
  Gaussian weights (centre c, both edge angles, edge width s, contrast a, offset b, shading g).
  Measured on rendered 1080p marker images: eq. 10 ~0.57 px RMS, the HTM fit ~0.06 px.

Both are numba-compiled loops (measured on 1080p marker ROIs: ~0.09 ms for a chain of ~7
corners, against ~0.7 ms for the batched numpy einsum version they replace, with the same
iterations, stopping rule and results to ~1e-13 px; the tanh come from separable exponentials).
Image frame as in cvs.corners.xcorners.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.corners.likelihood import CornerCandidates, Image
from wristmark.cvs.corners.xcorners import Array, DetectorSettings, IntArray

HTM_WEIGHT_PER_SPACING = 0.12  # the HTM fit's Gaussian weights: sigma per distance to the nearest other corner
HTM_WEIGHT_MAX_PX = 4.0  # ... capped here [px] (and at 1.5 px below)
CHAIN_END_SPACING = 0.6  # a chain end's spacing: this times its one step (chain_spacing)


def chain_spacing(points: Array) -> Array:
    """The spacing [px] (N,) that sets each corner's HTM window along a chain of ``points`` (N, 2)
    [px], in the chain's order: the distance to the nearer neighbour along the chain, and at its
    two ends ``CHAIN_END_SPACING`` times the one step there (foreshortening: the unseen next corner
    is closer than the last step). The detector's (cvs.corners.detector) and the tracker's drawing
    of a corner's fit (cvs.tracking.foreshortening) share it."""
    pts = np.asarray(points, float).reshape(-1, 2)
    if pts.shape[0] < 2:
        return np.full(pts.shape[0], np.inf)
    gaps = np.hypot(*np.diff(pts, axis=0).T)
    spacing = np.minimum(np.r_[gaps, np.inf], np.r_[np.inf, gaps])
    spacing[[0, -1]] *= CHAIN_END_SPACING
    return np.asarray(spacing, float)


def htm_weight_sigma(spacing: Array | float, max_px: float = HTM_WEIGHT_MAX_PX) -> Array:
    """The HTM fit's Gaussian weight sigma [px] for corners ``spacing`` [px] from the nearest
    other corner: 0.12 times that, in [1.5, ``max_px``] px (the detector's own: 4 px)."""
    return np.clip(HTM_WEIGHT_PER_SPACING * np.asarray(spacing, float), 1.5, float(max_px))


def _quadric_pinv(size: int) -> Array:
    r = size // 2
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    x, y = xx.ravel(), yy.ravel()
    return np.linalg.pinv(np.column_stack([x * x, y * y, x, y, x * y, np.ones_like(x)]))


_QPINV: dict[int, Array] = {}


@numba.njit(cache=True, nogil=True)
def _quadric_kernel(cl: Any, xs: Any, ys: Any, pinv: Any, out: Any) -> None:  # pragma: no cover
    """Eq. 9-10 per peak, written to out (n, 2) (see quadric_subpixel)."""
    r = int(round(math.sqrt(pinv.shape[1]))) // 2
    coef = np.empty(6)
    for k in range(xs.shape[0]):
        coef[:] = 0.0
        q = 0
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                v = np.float64(cl[ys[k] + dy, xs[k] + dx])
                for i in range(6):
                    coef[i] += pinv[i, q] * v
                q += 1
        a, b, c, d, e = coef[0], coef[1], coef[2], coef[3], coef[4]
        den = 4.0 * a * b - e * e
        out[k, 0], out[k, 1] = xs[k], ys[k]
        if den > 0.0 and a < 0.0:
            xo, yo = (d * e - 2.0 * b * c) / den, (c * e - 2.0 * a * d) / den
            if abs(xo) <= 1.0 and abs(yo) <= 1.0:
                out[k, 0] += xo
                out[k, 1] += yo


def quadric_subpixel(cl: NDArray[np.float32], xs: IntArray, ys: IntArray, size: int = 7) -> Array:
    """Eq. 9-10: extremum of the quadric fitted to the size x size CL patch around each integer
    peak -> (N, 2) sub-pixel positions [px]; the peak itself where the fit has no maximum within
    1 px. The patches must lie inside ``cl``."""
    if size not in _QPINV:
        _QPINV[size] = np.ascontiguousarray(_quadric_pinv(size))
    xs, ys = np.asarray(xs, np.int64).reshape(-1), np.asarray(ys, np.int64).reshape(-1)
    r = size // 2
    h, w = cl.shape
    if xs.size and (xs.min() < r or ys.min() < r or xs.max() >= w - r or ys.max() >= h - r):
        raise ValueError(f"quadric_subpixel: a {size}x{size} patch leaves the {w}x{h} image")
    out = np.empty((xs.size, 2))
    _quadric_kernel(cl, xs, ys, _QPINV[size], out)
    return out


@numba.njit(cache=True, nogil=True)
def _solve(A: Any, b: Any, x: Any) -> bool:  # pragma: no cover
    """x = A^-1 b by Gaussian elimination with partial pivoting (A, b overwritten); False when
    A is singular (as np.linalg.solve's LinAlgError)."""
    n = b.shape[0]
    for c in range(n):
        p = c
        for i in range(c + 1, n):
            if abs(A[i, c]) > abs(A[p, c]):
                p = i
        if A[p, c] == 0.0:
            return False
        if p != c:
            for j in range(n):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            b[c], b[p] = b[p], b[c]
        for i in range(c + 1, n):
            f = A[i, c] / A[c, c]
            for j in range(c, n):
                A[i, j] -= f * A[c, j]
            b[i] -= f * b[c]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[i, j] * x[j]
        x[i] = acc / A[i, i]
    return True


# One function on purpose (~100 lines): split into @njit helpers (window gathering, normal
# equations, step update) it gave identical results but ran 1.0-1.09x slower (median 1.013,
# six in-process A/B runs of 600 alternating rounds; docs/notes/renderer.md), and the fit is
# on the tracker's hot path, so it stays whole.
@numba.njit(cache=True, nogil=True)
def _htm_kernel(img: Any, ci: Any, sw: Any, th: Any, r: int, iters: int) -> None:  # pragma: no cover
    """Gauss-Newton on th (n, 9) = [cx, cy, ea, eb, s, a, b, gx, gy] in place: a linear start
    for (a, b, g), then up to ``iters`` damped steps for all corners together, stopping when
    every centre moved less than 2e-3 px or a normal matrix is singular. Windows of side 2r + 1
    centred at integer ci (n, 2) (inside img), Gaussian weights around the start (sigma sw)."""
    n = th.shape[0]
    m = (2 * r + 1) * (2 * r + 1)
    P = np.empty((n, m))
    X = np.empty((n, m))
    Y = np.empty((n, m))
    W = np.empty((n, m))
    for k in range(n):
        q = 0
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                x, y = ci[k, 0] + dx, ci[k, 1] + dy
                P[k, q] = img[y, x]
                X[k, q], Y[k, q] = x, y
                ex, ey = x - th[k, 0], y - th[k, 1]
                W[k, q] = math.exp(-0.5 * (ex * ex + ey * ey) / (sw[k] * sw[k]))
                q += 1
    J = np.empty(9)
    H = np.empty((9, 9))
    g = np.empty(9)
    step = np.empty((n, 9))
    sol = np.empty(9)
    side = 2 * r + 1
    exa, eya, exb, eyb = np.empty(side), np.empty(side), np.empty(side), np.empty(side)
    for it in range(iters + 1):
        for k in range(n):
            ca, sa = math.cos(th[k, 2]), math.sin(th[k, 2])
            cb, sb = math.cos(th[k, 3]), math.sin(th[k, 3])
            sg = 1.0 if cb * sa - sb * ca < 0.0 else -1.0  # sign of sin(eb - ea)
            s = th[k, 4]
            amp, off, gx, gy = th[k, 5], th[k, 6], th[k, 7], th[k, 8]
            # u_a, u_b are linear in the offsets: tanh(u/s) = 1 - 2 / (exp(2u/s) + 1) from per-row
            # and per-column exponentials (2 (2r+1) per edge instead of (2r+1)^2 tanh)
            for j in range(side):
                ox, oy = X[k, j] - th[k, 0], Y[k, j * side] - th[k, 1]
                exa[j], eya[j] = math.exp(-2.0 * sg * sa * ox / s), math.exp(2.0 * sg * ca * oy / s)
                exb[j], eyb[j] = math.exp(2.0 * sg * sb * ox / s), math.exp(-2.0 * sg * cb * oy / s)
            nv = 4 if it == 0 else 9
            H[:nv, :nv] = 0.0
            g[:nv] = 0.0
            for q in range(m):
                dx, dy = X[k, q] - th[k, 0], Y[k, q] - th[k, 1]
                ua = sg * (ca * dy - sa * dx)  # normal of a towards b
                ub = -sg * (cb * dy - sb * dx)  # normal of b towards a
                jy, jx = q // side, q % side
                ta = 1.0 - 2.0 / (exa[jx] * eya[jy] + 1.0)  # tanh(ua / s)
                tb = 1.0 - 2.0 / (exb[jx] * eyb[jy] + 1.0)  # tanh(ub / s)
                T = ta * tb
                if it == 0:  # linear start for a, b, g: basis [T, 1, dx, dy], target the grey levels
                    J[0], J[1], J[2], J[3] = T, 1.0, dx, dy
                    res = P[k, q]
                else:
                    res = P[k, q] - (amp * T + off + gx * dx + gy * dy)
                    dma = amp * (1.0 - ta * ta) / s * tb  # d model / d u_a
                    dmb = amp * (1.0 - tb * tb) / s * ta
                    J[0] = dma * sg * sa - dmb * sg * sb - gx  # d model / d cx
                    J[1] = -dma * sg * ca + dmb * sg * cb - gy
                    J[2] = -dma * sg * (sa * dy + ca * dx)  # d u_a / d ea
                    J[3] = dmb * sg * (sb * dy + cb * dx)
                    J[4] = -(dma * ua + dmb * ub) / s
                    J[5], J[6], J[7], J[8] = T, 1.0, dx, dy
                w = W[k, q]
                for i in range(nv):
                    wj = w * J[i]
                    g[i] += wj * res
                    for j in range(i, nv):
                        H[i, j] += wj * J[j]
            for i in range(nv):
                for j in range(i):
                    H[i, j] = H[j, i]
            if it == 0:
                for i in range(4):
                    H[i, i] += 1e-9
                if _solve(H[:4, :4], g[:4], sol[:4]):
                    th[k, 5:9] = sol[:4]
                continue
            for i in range(9):
                H[i, i] += 1e-6 * H[i, i] + 1e-12
            if not _solve(H, g, sol):
                return
            step[k, :] = sol
        if it == 0:
            continue
        done = True
        for k in range(n):
            for i in range(2):
                step[k, i] = min(max(step[k, i], -0.5), 0.5)
                step[k, i + 2] = min(max(step[k, i + 2], -0.2), 0.2)
            for i in range(9):
                th[k, i] += step[k, i]
            th[k, 4] = min(max(th[k, 4], 0.3), 4.0)
            if not (abs(step[k, 0]) < 2e-3 and abs(step[k, 1]) < 2e-3):
                done = False
        if done:
            return


@numba.njit(cache=True, nogil=True)
def _htm_fit(
    img: Any, pts: Any, edges: Any, sw: Any, r: int, iters: int, out: Any, eout: Any, ok: Any
) -> None:  # pragma: no cover
    """htm_refine's work: windows at the rounded points (clipped inside img), the fit, and the
    accepted results in out, eout (the inputs elsewhere)."""
    n = pts.shape[0]
    h, w = img.shape
    ci = np.empty((n, 2), np.int64)
    th = np.zeros((n, 9))  # cx cy ea eb s | a b gx gy
    for k in range(n):
        cx, cy = int(np.rint(pts[k, 0])), int(np.rint(pts[k, 1]))
        ok[k] = r <= cx < w - r and r <= cy < h - r
        ci[k, 0], ci[k, 1] = min(max(cx, r), w - r - 1), min(max(cy, r), h - r - 1)
        th[k, 0], th[k, 1], th[k, 2], th[k, 3], th[k, 4] = pts[k, 0], pts[k, 1], edges[k, 0], edges[k, 1], 1.0
    _htm_kernel(img, ci, sw, th, r, iters)
    for k in range(n):
        finite = True
        for i in range(9):
            finite &= np.isfinite(th[k, i])
        ok[k] = ok[k] and finite and math.hypot(th[k, 0] - pts[k, 0], th[k, 1] - pts[k, 1]) <= 1.5
        src = th[k] if ok[k] else pts[k]
        out[k, 0], out[k, 1] = src[0], src[1]
        esrc = th[k, 2:4] if ok[k] else edges[k]
        eout[k, 0], eout[k, 1] = esrc[0], esrc[1]


def htm_radius(sigma_w: Array | float, r: int = 4, window_sigmas: float = 0.0) -> NDArray[np.int64]:
    """The HTM fit's window half-size [px] for Gaussian weights ``sigma_w`` [px]: ``r``, or
    ``window_sigmas`` times the weights' sigma where that is larger (0: ``r`` for all), so that
    the window does not cut the weights short (4 px weights in a 9 x 9 window end at one sigma)."""
    sw = np.atleast_1d(np.asarray(sigma_w, float))
    if window_sigmas <= 0:
        return np.full(sw.shape, int(r), np.int64)
    return np.maximum(int(r), np.ceil(window_sigmas * sw - 1e-9)).astype(np.int64)


def htm_refine(
    img: Image, pts: Array, edges: Array, r: int = 4, sigma_w: Array | float = 4.0, iters: int = 3,
    window_sigmas: float = 0.0
) -> tuple[Array, Array, NDArray[np.bool_]]:
    """Least-squares fit of the HTM grey-level model b + a tanh(u_a/s) tanh(u_b/s) + g.(p - c) to
    the (2r+1)^2 patch of ``img`` around each point (Gaussian weights sigma_w [px]; with
    ``window_sigmas`` > 0 each point's r at least that many sigma_w, :func:`htm_radius`):
    Gauss-Newton on the centre c, both edge angles (as in XCorners.edges), s, a, b and g, started
    from the linear least-squares a, b, g at the given centre and edges (3 steps converge to
    ~1e-3 px). Returns points (N, 2) [px], edge angles (N, 2) [rad] and ok (N,): False (input
    returned) where the fit fails or moves more than 1.5 px."""
    pts = np.ascontiguousarray(pts, np.float64).reshape(-1, 2)
    edges = np.ascontiguousarray(edges, np.float64).reshape(-1, 2)
    n = pts.shape[0]
    sw = np.ascontiguousarray(np.broadcast_to(np.asarray(sigma_w, np.float64), (n,)))
    out, eout, ok = np.empty((n, 2)), np.empty((n, 2)), np.empty(n, np.bool_)
    if not n:
        return out, eout, ok
    radii = htm_radius(sw, r, window_sigmas)
    for radius in np.unique(radii):  # one kernel call per window size (one, or a few)
        k = np.flatnonzero(radii == radius)
        if k.size == n:
            _htm_fit(np.asarray(img), pts, edges, sw, int(radius), int(iters), out, eout, ok)
            break
        o, e, g = np.empty((k.size, 2)), np.empty((k.size, 2)), np.empty(k.size, np.bool_)
        sw_k = np.ascontiguousarray(sw[k])
        sw_k.flags.writeable = False  # as the whole call's (a broadcast view): the same compiled kernel
        _htm_fit(np.asarray(img), np.ascontiguousarray(pts[k]), np.ascontiguousarray(edges[k]),
                 sw_k, int(radius), int(iters), o, e, g)
        out[k], eout[k], ok[k] = o, e, g
    return out, eout, ok


def subpixel(
    cands: CornerCandidates, idx: IntArray, s: DetectorSettings, spacing: Array
) -> tuple[Array, Array, Array]:
    """(refined, quadric, edges) of candidates ``idx`` in the candidates' image pixels;
    ``spacing`` [px]: distance to the nearest other corner (sets the HTM fit's Gaussian window,
    sigma = 0.12 spacing in [1.5, 4] px). The HTM fit starts from the integer CL peak: on rendered
    marker corners the 7x7 quadric of eq. 9-10 is often further from the corner than the peak
    itself (CL is too sharply peaked for a 7x7 quadric)."""
    xs, ys = cands.xs[idx], cands.ys[idx]
    q = quadric_subpixel(cands.cl, xs, ys, s.quad_size)
    edges = cands.edges[idx]
    if not s.refine or idx.size == 0:
        return q, q.copy(), edges
    ref, e, ok = htm_refine(cands.gray, cands.points(idx), edges, s.refine_radius, htm_weight_sigma(spacing),
                            window_sigmas=s.refine_window_sigmas)
    ref[~ok] = q[~ok]
    return ref, q, e
