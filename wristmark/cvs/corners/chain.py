"""The marker chain (step 5 of cvs.corners.detector, paper Fig. 4).

Candidates are tried in decreasing normalised CL order until one is an X-corner that grows a
chain of ``min_corners``: the second corner is the nearest found by moving the window along the
four edge directions; then the chain grows outward both ways along the local edge direction
closest to the last step (turned by half the change of that edge since the previous corner: the
corner circle's image is curved) and, where that finds nothing, along the last step itself (a
highlight stripe over a corner can bend its edge along the chain by 20 deg and turn the search
off the line: docs/notes/highlight-stripe.md), until the searched distance exceeds
``stop_ratio`` times the last spacing. Consecutive corners alternate in polarity, taken
relative to the chain's direction (``along_polarity``: the detector's own flips where a steeply
seen sleeve's edges both lean ~45 deg). ``find_chain(..., gaps=k)``: a chain that stops may
step, up to k times, over one missed corner: the next corner of the *same* polarity between 1.5
and ``gap_ratio`` times the last spacing along the same direction (a specular highlight washing
out the corner the camera sees best, docs/notes/highlight-stripe.md), searched along the
extrapolated turn and, where that finds nothing, along the last step; a step over that finds
nothing does not count against k. The stereo match then indexes it two steps on (repeated
polarity).

A window search moves the paper's 10x10 square (widened across the step to 20% of the distance
so that a curved corner circle stays inside it) in half-window steps and takes the first window
whose CL maximum is an X-corner of the other polarity, with an edge along the step and a
grey-level range at least ``contrast_ratio`` times that of the current corner (rejects X-like
texture next to the marker). Candidates are X-tested lazily, when they are reached as a seed or
as a window's maximum (the visiting order, hence the chain, is that of testing all of them).

All of it is numba-compiled (measured on 1080p marker ROIs: ~0.06 ms per image with the X-corner
tests, against ~1.3 ms for the Python search over batch-tested candidates it replaces).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from wristmark.cvs.corners.likelihood import CornerCandidates
from wristmark.cvs.corners.xcorner_test import NBINS, classify_candidate
from wristmark.cvs.corners.xcorners import Array, DetectorSettings, IntArray

_MAX_CHAIN = 64  # corners per chain, at most
# The compiled functions pass three tuples:
#   c   = (xs, ys, normalised CL, grey range, tested, ok, |CC|, polarity, edges) of the candidates
#   im  = (grey, I_x, I_y, histogram scratch)
#   prm = (half_window, template_scale, cc_min, contrast_ratio, cos(edge_tol), max_step_px,
#          stop_ratio, min_corners, max_seeds, seed_candidates, max_gaps, gap_ratio, cos(cross_edge_tol),
#          chain_polarity == "along")


@numba.njit(cache=True, nogil=True)
def _xtest(c: Any, im: Any, prm: Any, k: int) -> None:  # pragma: no cover
    """The X-corner test of candidate k (cvs.corners.xcorner_test), once; im = (grey, I_x, I_y, scratch)."""
    xs, ys, _, _, tested, ok, cc, pol, edges = c
    classify_candidate(im[0], im[1], im[2], xs, ys, k, prm[0], prm[1], prm[2], tested, ok, cc, pol, edges, im[3])


@numba.njit(cache=True, nogil=True)
def _along_polarity(pol: Any, edges: Any, k: int, dx: float, dy: float, along: bool) -> int:  # pragma: no cover
    """Candidate k's polarity relative to the line (dx, dy) it lies on (along_polarity; not
    ``along``: the X-corner test's own)."""
    if not along:
        return int(pol[k])
    ca, sa, cb, sb = math.cos(edges[k, 0]), math.sin(edges[k, 0]), math.cos(edges[k, 1]), math.sin(edges[k, 1])
    cross = 1 if ca * sb - sa * cb >= 0.0 else -1
    a_along = abs(ca * dx + sa * dy) >= abs(cb * dx + sb * dy)
    return int(-pol[k] * cross if a_along else pol[k] * cross)


def along_polarity(polarity: IntArray, edges: Array, directions: Array) -> IntArray:
    """Polarities (N,) +-1 relative to each corner's chain direction ``directions`` (N, 2) (either
    sense). The detector's polarity orders a corner's two edges by which is closer to vertical
    (cvs.corners.xcorner_test); where both lean ~45 deg (a sleeve seen steeply) that order flips
    from one corner to the next and so does the polarity. Here the edge along the chain comes
    first and the other one is turned to its right (image y down): the same value wherever the
    chain's edge is the more vertical one, and alternating along any chain. A sign of the sector
    between two edges flips with each edge's sense, so the chain's sense drops out."""
    ca, sa, cb, sb = np.cos(edges[:, 0]), np.sin(edges[:, 0]), np.cos(edges[:, 1]), np.sin(edges[:, 1])
    cross = np.where(ca * sb - sa * cb >= 0.0, 1, -1)
    dx, dy = directions[:, 0], directions[:, 1]
    a_along = np.abs(ca * dx + sa * dy) >= np.abs(cb * dx + sb * dy)
    return np.asarray(np.where(a_along, -polarity * cross, polarity * cross), int)


@numba.njit(cache=True, nogil=True)
def _cross_edge(edges: Any, k: int, dx: float, dy: float) -> float:  # pragma: no cover
    """Candidate k's edge across the line (dx, dy): the one of its two less parallel to it [rad]."""
    ca, sa, cb, sb = math.cos(edges[k, 0]), math.sin(edges[k, 0]), math.cos(edges[k, 1]), math.sin(edges[k, 1])
    return float(edges[k, 1] if abs(ca * dx + sa * dy) >= abs(cb * dx + sb * dy) else edges[k, 0])


@numba.njit(cache=True, nogil=True)
def _search(
    c: Any, im: Any, prm: Any, cur: int, dx: float, dy: float, max_dist: float, used: Any, skip: bool = False,
    min_dist: float = 0.0,
) -> int:  # pragma: no cover
    """The window search from candidate ``cur`` along unit (dx, dy) up to ``max_dist`` [px]
    (module doc); the candidate index or -1. ``skip``: a corner of the same polarity at least
    ``min_dist`` [px] away (the next one beyond a corner the search did not find)."""
    xs, ys, cln, rng, _, ok, _, pol, edges = c
    r = prm[0]
    min_rng = np.float32(prm[3] * np.float64(rng[cur]))
    cos_tol = prm[4]
    px, py = np.float64(xs[cur]), np.float64(ys[cur])
    here = _along_polarity(pol, edges, cur, dx, dy, prm[13])
    want = here if skip else -here
    across = _cross_edge(edges, cur, dx, dy)
    cos_cross = prm[12]
    n = xs.size
    band = np.empty(n, np.int64)
    al = np.empty(n)
    ac = np.empty(n)
    nb = 0
    for k in range(n):
        rx, ry = xs[k] - px, ys[k] - py
        a = rx * dx + ry * dy
        b = abs(rx * (-dy) + ry * dx)
        if a > 1.0 and a <= max_dist + r and b <= max(r, 0.2 * (a + r)):
            band[nb], al[nb], ac[nb] = k, a, b
            nb += 1
    if nb == 0:
        return -1
    band, al, ac = band[:nb], al[:nb], ac[:nb]
    o1 = np.argsort(ac, kind="mergesort")
    order = o1[np.argsort(al[o1], kind="mergesort")]  # by (along, across, index)
    t = float(r + 1)
    while t <= max_dist + 1e-9:
        lat = max(r, 0.2 * t)
        best = -1
        for j in order:
            if abs(al[j] - t) <= r and ac[j] <= lat:
                k = band[j]
                if best < 0 or cln[k] > cln[best]:  # the window's CL maximum (first of equals)
                    best = k
        t += r
        if best < 0:
            continue
        k = best
        if used[k]:
            continue
        _xtest(c, im, prm, k)  # lazily: only window maxima need the X-corner test
        if not ok[k] or _along_polarity(pol, edges, k, dx, dy, prm[13]) != want or rng[k] < min_rng:
            continue
        sx, sy = xs[k] - px, ys[k] - py
        dist = math.hypot(sx, sy)
        if dist < max(2.0, min_dist) or dist > max_dist + r:
            continue
        ux, uy = sx / dist, sy / dist
        along_a = abs(math.cos(edges[k, 0]) * ux + math.sin(edges[k, 0]) * uy)
        along_b = abs(math.cos(edges[k, 1]) * ux + math.sin(edges[k, 1]) * uy)
        if max(along_a, along_b) < cos_tol:
            continue
        if abs(math.cos(_cross_edge(edges, k, dx, dy) - across)) < cos_cross:
            continue  # the squares' edges across the chain are (nearly) parallel, not texture's
        return k
    return -1


@numba.njit(cache=True, nogil=True)
def _best_edge(edges: Any, k: int, ux: float, uy: float) -> tuple[float, float]:  # pragma: no cover
    """The edge direction (of four) of candidate k closest to unit vector (ux, uy)."""
    bx, by, bd = 0.0, 0.0, -1.0
    for j in range(2):
        cx, cy = math.cos(edges[k, j]), math.sin(edges[k, j])
        d = cx * ux + cy * uy
        if abs(d) > bd:
            sign = 1.0 if d >= 0.0 else -1.0
            bx, by, bd = sign * cx, sign * cy, abs(d)
    return bx, by


@numba.njit(cache=True, nogil=True)
def _grow(c: Any, im: Any, prm: Any, seed: int, out: Any) -> int:  # pragma: no cover
    """The chain through ``seed`` written to ``out`` in order along the chain; its length."""
    xs, ys, _, _, _, _, _, _, edges = c
    used = np.zeros(xs.size, np.bool_)
    used[seed] = True
    best, best_d = -1, math.inf
    for j in range(2):
        for sign in (1.0, -1.0):
            ea = edges[seed, j]
            k = _search(c, im, prm, seed, sign * math.cos(ea), sign * math.sin(ea), prm[5], used)
            if k >= 0:
                d = math.hypot(xs[k] - np.float64(xs[seed]), ys[k] - np.float64(ys[seed]))
                if d < best_d:
                    best, best_d = k, d
    if best < 0:
        out[0] = seed
        return 1
    buf = np.empty(2 * _MAX_CHAIN + 2, np.int64)
    head, tail = _MAX_CHAIN, _MAX_CHAIN + 2  # chain = buf[head:tail]
    buf[head], buf[head + 1] = seed, best
    used[best] = True
    gaps = 0
    for forward in (True, False):
        while tail - head < _MAX_CHAIN:
            cur, prev = (buf[tail - 1], buf[tail - 2]) if forward else (buf[head], buf[head + 1])
            sx, sy = xs[cur] - np.float64(xs[prev]), ys[cur] - np.float64(ys[prev])
            dist = math.hypot(sx, sy)
            ux, uy = sx / dist, sy / dist
            cx, cy = _best_edge(edges, cur, ux, uy)
            qx, qy = _best_edge(edges, prev, ux, uy)
            a = math.atan2(cy, cx)  # the current edge turned on by half its change since prev
            da = math.atan2(qx * cy - qy * cx, qx * cx + qy * cy)
            ex, ey = math.cos(a + 0.5 * da), math.sin(a + 0.5 * da)
            k = _search(c, im, prm, cur, ex, ey, prm[6] * dist, used)
            if k < 0:  # a highlight can bend the current corner's edge: the straight continuation too
                k = _search(c, im, prm, cur, ux, uy, prm[6] * dist, used)
            if k < 0 and gaps < prm[10]:  # beyond one missed corner (a highlight over it): same polarity
                k = _search(c, im, prm, cur, ex, ey, prm[11] * dist, used, True, 1.5 * dist)
                if k < 0:  # over two spacings the turn extrapolated from a limb corner can overshoot
                    k = _search(c, im, prm, cur, ux, uy, prm[11] * dist, used, True, 1.5 * dist)
                gaps += k >= 0  # a step over that finds nothing leaves the other end its own
            if k < 0:
                break
            used[k] = True
            if forward:
                buf[tail] = k
                tail += 1
            else:
                head -= 1
                buf[head] = k
    n = tail - head
    out[:n] = buf[head:tail]
    return n


@numba.njit(cache=True, nogil=True)
def _chain_kernel(c: Any, im: Any, prm: Any) -> Any:  # pragma: no cover
    """Seeds in decreasing normalised CL order until a chain of min_corners (module doc)."""
    ok = c[5]
    min_corners, max_seeds, seed_candidates = prm[7], prm[8], prm[9]
    n = min(c[0].size, seed_candidates)
    out = np.empty(_MAX_CHAIN, np.int64)
    seeds = 0
    for k in range(n):
        _xtest(c, im, prm, k)  # lazily: a seed's test only when it is reached
        if not ok[k]:
            continue
        m = _grow(c, im, prm, k, out)
        if m >= min_corners:
            return out[:m].copy()
        seeds += 1
        if seeds >= max_seeds:
            break
    return out[:0].copy()


@numba.njit(cache=True, nogil=True)
def _pairs_kernel(c: Any, im: Any, prm: Any, max_pairs: int) -> Any:  # pragma: no cover
    """Seeds in decreasing normalised CL order (as _chain_kernel, up to max_seeds X-corners):
    each seed's chain, where it has exactly two corners; each unordered pair once."""
    ok = c[5]
    max_seeds, seed_candidates = prm[8], prm[9]
    n = min(c[0].size, seed_candidates)
    out = np.empty(_MAX_CHAIN, np.int64)
    pairs = np.empty((max_pairs, 2), np.int64)
    found = seeds = 0
    for k in range(n):
        _xtest(c, im, prm, k)
        if not ok[k]:
            continue
        m = _grow(c, im, prm, k, out)
        if m == 2:
            a, b = min(out[0], out[1]), max(out[0], out[1])
            new = True
            for j in range(found):
                if pairs[j, 0] == a and pairs[j, 1] == b:
                    new = False
            if new:
                pairs[found, 0], pairs[found, 1] = out[0], out[1]
                found += 1
                if found >= max_pairs:
                    break
        seeds += 1
        if seeds >= max_seeds:
            break
    return pairs[:found].copy()


def _params(s: DetectorSettings, gaps: int) -> tuple[Any, ...]:
    return (
        int(s.half_window), float(s.template_scale), float(s.cc_min), float(s.contrast_ratio),
        math.cos(math.radians(s.edge_tol_deg)), float(s.max_step_px), float(s.stop_ratio), int(s.min_corners),
        int(s.max_seeds), int(s.seed_candidates), max(int(gaps), 0), float(s.gap_ratio),
        math.cos(math.radians(s.cross_edge_tol_deg)), s.chain_polarity == "along",
    )


def find_pairs(cands: CornerCandidates, s: DetectorSettings, max_pairs: int = 8) -> IntArray:
    """Candidate index pairs (M, 2), M <= ``max_pairs``, of the seeds (tried as :func:`find_chain`
    tries them) whose chain stops at two corners: a sleeve seen so steeply that only the two
    corners facing the camera pass the X-corner test (MarkerTracker's last try on a coded
    sleeve, cvs.tracking.two_pairs). Each unordered pair once, in the order found."""
    c = cands
    arrays = (c.xs, c.ys, c.cln, c.rng, c.tested, c.ok, c.cc, c.pol, c.edges)
    pairs: IntArray = _pairs_kernel(arrays, (c.gray, c.ix, c.iy, np.empty((2, NBINS))), _params(s, 0),
                                    max(int(max_pairs), 1))
    return pairs


def find_chain(cands: CornerCandidates, s: DetectorSettings, gaps: int = 0) -> IntArray:
    """Candidate indices of the marker chain (module doc), ordered along the chain; empty when
    no seed grows a chain of ``s.min_corners``. ``gaps``: missed corners the chain may step over
    (0: the paper's chain)."""
    c = cands
    arrays = (c.xs, c.ys, c.cln, c.rng, c.tested, c.ok, c.cc, c.pol, c.edges)
    chain: IntArray = _chain_kernel(arrays, (c.gray, c.ix, c.iy, np.empty((2, NBINS))), _params(s, gaps))
    return chain
