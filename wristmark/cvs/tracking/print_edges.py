"""The sleeve's printed edges as extra features of the pose.

A sleeve seen almost side-on shows one arc of 3-4 X-corners, all at z = 0: they fix the tilt of
its axis poorly (docs/notes/print-bars.md, "Why"). The print has more: the checker rows'
edges along and around the sleeve up to z = +-row_height, and a coded sleeve's code cells up to
+-5 mm. :func:`printed_edges` lists sample points on every dark/white boundary of the print in
{wm}; :func:`measure_edges` finds each one's edge in an image along the image normal of the
boundary near the predicted pose (the largest grey-level step of the expected sign, sub-pixel);
:func:`refine_with_edges` solves the pose again from the corners and those edges together.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.gray_image import to_gray
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]
BLUR_FIT_PX = 7.5  # [px] the blurred-step fit's profile, +-this along the edge's normal (measure_edges)
BLUR_FIT_RESIDUAL = 0.06  # its largest RMS residual, a fraction of the fitted step
BLUR_FIT_MAX_SIGMA = 2.5  # [px] its largest fitted blur (measure_edges; 6 or more: no bound but the fit's own)
_SQRT2 = math.sqrt(2.0)
_SQRT2PI = math.sqrt(2.0 * math.pi)

__all__ = ["EdgeMeasurements", "PrintedEdges", "bar_pairs", "edges_tip_sigma", "measure_edges", "print_is_negative",
           "printed_edges", "refine_with_edges", "run_kernels_once"]


@dataclass(frozen=True)
class PrintedEdges:
    """Sample points on the print's dark/white boundaries, in {wm} [m], in pairs across one dark
    bar: ``points`` (M, 3), ``across`` (M, 3) the unit tangent of the surface across the boundary
    towards its white side, ``normals`` (M, 3) the outward surface normal, ``partner`` (M,) the
    sample on the bar's other boundary at the same height (along the sleeve) or angle (around
    it), ``coded`` (M,) True where the bar lies outside the checker rows (a coded sleeve's code
    cells: their place needs the roll)."""

    points: Array
    across: Array
    normals: Array
    partner: NDArray[np.intp]
    coded: NDArray[np.bool_]


@functools.lru_cache(maxsize=16)
def _printed_edges(radius: float, columns: int, row_height: float, patches: tuple[tuple[float, ...], ...],
                   fractions: tuple[float, ...], min_white: float) -> PrintedEdges:
    marker = MarkerModel(radius=radius, columns=columns, row_height=row_height,
                         patches=tuple(tuple(p) for p in patches))  # type: ignore[arg-type, misc]
    two_pi = 2.0 * math.pi
    angles = sorted({round((k * marker.beta) % two_pi, 12) for k in range(columns)}
                    | {round(a % two_pi, 12) for p in patches for a in p[:2]})
    z_lo, z_hi = marker.z_extent
    zs = sorted({0.0, -row_height, row_height} | {float(z) for p in patches for z in p[2:]})
    zs = [z for z in zs if z_lo <= z <= z_hi]
    rows: list[tuple[list[float], list[float], list[float], bool]] = []
    partner: list[int] = []

    def add(a: float, z: float, across: list[float], coded: bool) -> int:
        rows.append(([radius * math.cos(a), radius * math.sin(a), z], across, [math.cos(a), math.sin(a), 0.0], coded))
        partner.append(-1)
        return len(rows) - 1

    def pair(i: int, j: int) -> None:
        partner[i], partner[j] = j, i

    for z0, z1 in zip(zs[:-1], zs[1:]):  # dark runs around the sleeve, between two heights
        zm = 0.5 * (z0 + z1)
        starts = [a for a in angles if not marker.is_black(a - 1e-6, zm) and marker.is_black(a + 1e-6, zm)]
        ends = [a for a in angles if marker.is_black(a - 1e-6, zm) and not marker.is_black(a + 1e-6, zm)]
        for a_s in starts:
            a_e = min(ends, key=lambda e: (e - a_s) % two_pi)
            for f in fractions:
                z = z0 + f * (z1 - z0)
                coded = abs(zm) > row_height
                i = add(a_s, z, [math.sin(a_s), -math.cos(a_s), 0.0], coded)  # white before the start
                j = add(a_e, z, [-math.sin(a_e), math.cos(a_e), 0.0], coded)  # white after the end
                pair(i, j)
    for a0, a1 in zip(angles, angles[1:] + [angles[0] + two_pi]):  # dark runs along the sleeve
        am = 0.5 * (a0 + a1)
        dark = [marker.is_black(am, 0.5 * (za + zb)) for za, zb in zip(zs[:-1], zs[1:])]
        k = 0
        while k < len(dark):
            if not dark[k]:
                k += 1
                continue
            e = k
            while e + 1 < len(dark) and dark[e + 1]:
                e += 1
            z_s, z_e = zs[k], zs[e + 1]
            below = next((zs[j + 1] for j in range(k - 1, -1, -1) if dark[j]), z_lo)
            above = next((zs[j] for j in range(e + 2, len(dark)) if dark[j]), z_hi)
            # not at the sleeve's ends (no white beyond) nor at z = 0 (the X-corners' line), and
            # white for min_white beyond each boundary (a narrow white gap's blurred edges move)
            if (z_lo < z_s and z_e < z_hi and z_s != 0.0 and z_e != 0.0
                    and z_s - below >= min_white - 1e-12 and above - z_e >= min_white - 1e-12):
                for f in fractions:
                    a = a0 + f * (a1 - a0)
                    i = add(a, z_s, [0.0, 0.0, -1.0], True)
                    j = add(a, z_e, [0.0, 0.0, 1.0], True)
                    pair(i, j)
            k = e + 1
    return PrintedEdges(np.array([r[0] for r in rows], float).reshape(-1, 3),
                        np.array([r[1] for r in rows], float).reshape(-1, 3),
                        np.array([r[2] for r in rows], float).reshape(-1, 3),
                        np.array(partner, np.intp), np.array([r[3] for r in rows], bool))


def printed_edges(marker: MarkerModel, fractions: tuple[float, ...] = (0.3, 0.5, 0.7),
                  min_white: float = 0.6e-3) -> PrintedEdges:
    """Sample points at ``fractions`` of every straight piece of the print's dark/white
    boundaries of ``marker`` (the checker rows and any patches; not the sleeve's two ends), in
    {wm} [m]. Cached per marker geometry."""
    patches = tuple(tuple(float(v) for v in p) for p in marker.patch_array())
    return _printed_edges(float(marker.radius), int(marker.columns), float(marker.row_height), patches,
                          tuple(float(f) for f in fractions), float(min_white))


@dataclass(frozen=True)
class EdgeMeasurements:
    """Edges found in one view: ``index`` (K,) into the :class:`PrintedEdges` samples, ``uv``
    (K, 2) [px] the measured edge points, ``normal`` (K, 2) the unit image normal of each
    boundary (dark to white) along which it was measured."""

    index: NDArray[np.intp]
    uv: Array
    normal: Array


def _grey_patch(view: NDArray[np.uint8], uv: Array, margin: float) -> tuple[NDArray[np.float32], tuple[int, int]]:
    """The grey levels (float) of the box around ``uv`` with ``margin`` [px], and its origin (x, y)."""
    h, w = view.shape[:2]
    x0 = max(int(math.floor(uv[:, 0].min() - margin)), 0)
    y0 = max(int(math.floor(uv[:, 1].min() - margin)), 0)
    x1 = min(int(math.ceil(uv[:, 0].max() + margin)) + 1, w)
    y1 = min(int(math.ceil(uv[:, 1].max() + margin)) + 1, h)
    crop = view[y0:y1, x0:x1]
    return to_gray(crop).astype(np.float32), (x0, y0)


def measure_edges(view: NDArray[np.uint8], camera: StereoCamera, right: bool, T_left_marker: Array,
                  edges: PrintedEdges, use: NDArray[np.bool_] | None = None, search_px: float = 3.5,
                  min_step: float = 12.0, clipped_level: int = 250, min_facing: float = 0.5,
                  blur_fit_px: float = BLUR_FIT_PX, blur_fit_residual: float = BLUR_FIT_RESIDUAL,
                  blur_fit_max_sigma_px: float = BLUR_FIT_MAX_SIGMA) -> EdgeMeasurements:
    """Each printed edge sample (``use``: which; default all) that faces the view's camera by
    ``min_facing`` or more (cosine between the surface normal and the line of sight), found in
    ``view`` (the left or, with ``right``, the right image) along its boundary's image normal
    within ``search_px`` of where the pose ``T_left_marker`` ({wm} in {ll}) puts it: the largest
    step from dark to white (central differences of the bilinear profile at 0.5 px, the peak
    refined by a parabola), kept where the profile spans ``min_step`` grey levels or more, has
    no pixel at ``clipped_level`` or more (a highlight) and peaks inside the search. Samples
    whose bar partner does not face the camera are not searched. A sample those tests refuse (a
    blurred edge rises too slowly) is measured by a
    blurred step a + b Phi((t - t0) / sigma) fitted to the unclipped samples of its profile over
    +-``blur_fit_px`` (0: off), kept where t0 lies inside the search, b spans ``min_step`` or
    more, a + b lies under ``clipped_level`` (the white level is seen, not extrapolated from a
    clipped half), the fit's RMS residual is within ``blur_fit_residual`` times b and its sigma
    is ``blur_fit_max_sigma_px`` or less (a sharp step into a shading ramp fits as a wider blur
    placed in the ramp; bench/bar_edges.py: on path-traced 1515/15 the largest gradient is 0.95 px
    off, this fit 0.19)."""
    R, t = T_left_marker[:3, :3], T_left_marker[:3, 3]
    sel = np.arange(edges.points.shape[0]) if use is None else np.flatnonzero(use)
    P = edges.points[sel] @ R.T + t
    n = edges.normals[sel] @ R.T
    centre = -camera.R.T @ np.asarray(camera.T, float).reshape(3) if right else np.zeros(3)
    sight = centre - P
    facing = np.einsum("ij,ij->i", n, sight) / np.linalg.norm(sight, axis=1)
    keep = facing >= min_facing
    facing_all = np.zeros(edges.points.shape[0], bool)
    facing_all[sel[keep]] = True
    keep &= facing_all[edges.partner[sel]]  # a bar needs both its boundaries
    project = camera.project_right if right else camera.project_left
    empty = EdgeMeasurements(np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros((0, 2)))
    if not keep.any():
        return empty
    sel, P = sel[keep], P[keep]
    step_m = 1e-5  # 10 um along the surface: the boundary's image normal
    both = np.asarray(project(np.vstack([P, P + step_m * (edges.across[sel] @ R.T)])), float).reshape(-1, 2)
    uv, d = both[:sel.size], both[sel.size:] - both[:sel.size]
    length = np.linalg.norm(d, axis=1)
    ok = length > 1e-9
    h, w = view.shape[:2]
    lo = search_px + 2
    ok &= (uv[:, 0] > lo) & (uv[:, 0] < w - lo - 1) & (uv[:, 1] > lo) & (uv[:, 1] < h - lo - 1)
    if not ok.any():
        return empty
    sel, uv, u = sel[ok], uv[ok], d[ok] / length[ok, None]
    grey, (x0, y0) = _grey_patch(view, uv, max(search_px, blur_fit_px) + 2.0)
    offset, good = _profile_peaks(grey, float(x0), float(y0), uv, u, float(search_px), float(min_step),
                                  float(clipped_level), float(blur_fit_px), float(blur_fit_residual),
                                  float(blur_fit_max_sigma_px))
    return EdgeMeasurements(sel[good], uv[good] + offset[good, None] * u[good], u[good])


@numba.njit(cache=True, nogil=True)
def _bilinear(grey: NDArray[np.float32], x: float, y: float) -> float:  # pragma: no cover (jit)
    """``grey`` at (x, y) [px of the crop], bilinear, clamped to the crop."""
    h, w = grey.shape
    x = min(max(x, 0.0), w - 1.0)
    y = min(max(y, 0.0), h - 1.0)
    xi, yi = min(int(x), w - 2), min(int(y), h - 2)
    fx, fy = x - xi, y - yi
    return float((1 - fy) * ((1 - fx) * grey[yi, xi] + fx * grey[yi, xi + 1])
                 + fy * ((1 - fx) * grey[yi + 1, xi] + fx * grey[yi + 1, xi + 1]))


@numba.njit(cache=True, nogil=True)
def _blurred_step(t: Array, v: Array, t_start: float, span: float,
                  ) -> tuple[float, float, float, float, float]:  # pragma: no cover (jit)
    """Levenberg-Marquardt fit of v ~ a + b Phi((t - t0) / sigma) (sigma in [0.3, 6] px, |t0| <= 6
    px, b >= 1): (t0, a, b, RMS residual, sigma)."""
    n = t.size
    a, b, t0, sg = float(v.min()), max(span, 1.0), t_start, 1.5
    lam = 1e-3
    J = np.empty((n, 4))
    r = np.empty(n)

    def cost(a: float, b: float, t0: float, sg: float) -> float:
        c = 0.0
        for i in range(n):
            e = a + b * 0.5 * (1.0 + math.erf((t[i] - t0) / (_SQRT2 * sg))) - v[i]
            c += e * e
        return c

    c0 = cost(a, b, t0, sg)
    done = False
    for _ in range(60):
        for i in range(n):
            z = (t[i] - t0) / (_SQRT2 * sg)
            g = math.exp(-z * z) / (_SQRT2PI * sg)
            J[i, 0] = 1.0
            J[i, 1] = 0.5 * (1.0 + math.erf(z))
            J[i, 2] = -b * g
            J[i, 3] = -b * g * (t[i] - t0) / sg
            r[i] = a + b * J[i, 1] - v[i]
        A = J.T @ J
        gvec = J.T @ r
        improved = False
        for _ in range(8):
            M = A.copy()
            for k in range(4):
                M[k, k] += lam * (A[k, k] + 1e-9)
            step = np.linalg.solve(M, -gvec)
            na, nb = a + step[0], max(b + step[1], 1.0)
            nt, ns = min(max(t0 + step[2], -6.0), 6.0), min(max(sg + step[3], 0.3), 6.0)
            c1 = cost(na, nb, nt, ns)
            if c1 < c0:
                done = c0 - c1 < 1e-10 * (c0 + 1e-12)
                a, b, t0, sg, c0 = na, nb, nt, ns, c1
                lam = max(lam * 0.3, 1e-9)
                improved = True
                break
            lam *= 10.0
        if not improved or done:
            break
    return t0, a, b, math.sqrt(c0 / n), sg


@numba.njit(cache=True, nogil=True)
def _profile_peaks(grey: NDArray[np.float32], x0: float, y0: float, uv: Array, u: Array, search_px: float,
                   min_step: float, clipped: float, blur_px: float, blur_residual: float,
                   blur_max_sigma: float) -> tuple[Array, NDArray[np.bool_]]:  # pragma: no cover (jit)
    """Per sample k, the profile of ``grey`` (a crop whose pixel (0, 0) is image pixel (x0, y0))
    along ``u[k]`` through ``uv[k]`` [px], bilinear at 0.5 px from -search_px - 0.5 to
    search_px + 0.5: the offset [px] along ``u[k]`` of its largest dark-to-white step (central
    differences, the peak refined by a parabola), and whether it counts (peak inside the search,
    the profile spans ``min_step`` grey levels or more with no level at ``clipped`` or more, and
    the step is at least a quarter of that span per px); where it does not, with ``blur_px`` > 0,
    the blurred step fitted over +-``blur_px`` to the unclipped levels, its sigma at most
    ``blur_max_sigma`` [px] (measure_edges)."""
    n_s = int(round(2.0 * (search_px + 0.5) / 0.5)) + 1
    k_n = uv.shape[0]
    offset = np.zeros(k_n)
    good = np.zeros(k_n, np.bool_)
    prof = np.empty(n_s)
    for k in range(k_n):
        lo_v, hi_v = 1e30, -1e30
        for i in range(n_s):
            t = -search_px - 0.5 + 0.5 * i
            v = _bilinear(grey, uv[k, 0] + t * u[k, 0] - x0, uv[k, 1] + t * u[k, 1] - y0)
            prof[i] = v
            lo_v, hi_v = min(lo_v, v), max(hi_v, v)
        best, j = -1e30, 0
        for i in range(n_s - 2):  # gradient at sample i + 1
            g = 0.5 * (prof[i + 2] - prof[i])
            if g > best:
                best, j = g, i
        n_g = n_s - 2
        if 0 < j < n_g - 1:
            g0, g1, g2 = 0.5 * (prof[j + 1] - prof[j - 1]), best, 0.5 * (prof[j + 3] - prof[j + 1])
            den = g0 - 2.0 * g1 + g2
            frac = 0.5 * (g0 - g2) / den if den < 0 else 0.0
            frac = min(max(frac, -0.5), 0.5)
            offset[k] = -search_px + 0.5 * j + 0.5 * frac
            span = hi_v - lo_v
            good[k] = span >= min_step and hi_v < clipped and g1 > 0.25 * span * 0.5
        else:
            offset[k] = -search_px + 0.5 * j
        if good[k] or blur_px <= 0.0:
            continue
        m = int(round(2.0 * blur_px / 0.5)) + 1
        ts, vs = np.empty(m), np.empty(m)
        nv, lo_b, hi_b = 0, 1e30, -1e30
        for i in range(m):
            t = -blur_px + 0.5 * i
            v = _bilinear(grey, uv[k, 0] + t * u[k, 0] - x0, uv[k, 1] + t * u[k, 1] - y0)
            if v < clipped:
                ts[nv], vs[nv] = t, v
                nv += 1
                lo_b, hi_b = min(lo_b, v), max(hi_b, v)
        if nv < 8 or hi_b - lo_b < min_step:
            continue
        start = min(max(offset[k], -search_px), search_px)
        t0, a, b, rms, sg = _blurred_step(ts[:nv], vs[:nv], start, hi_b - lo_b)
        # the white level fitted must be one the profile shows (under the clip): a step whose
        # white half is clipped away leaves its height, blur and place to trade off
        if (abs(t0) <= search_px and b >= min_step and a + b < clipped and rms <= blur_residual * b
                and sg <= blur_max_sigma):
            offset[k], good[k] = t0, True
    return offset, good


def run_kernels_once() -> None:
    """Load (or, first time, compile) this module's numba kernel (cvs.tracking.warmup)."""
    grey = np.zeros((16, 16), np.float32)
    grey[:, 8:] = 200.0
    _profile_peaks(grey, 0.0, 0.0, np.array([[8.0, 8.0]]), np.array([[1.0, 0.0]]), 3.5, 12.0, 250.0, 0.0, 0.06, 6.0)
    grey[:, 7] = 100.0  # a blurred step: the fit's kernel too
    _profile_peaks(grey, 0.0, 0.0, np.array([[8.0, 8.0]]), np.array([[1.0, 0.0]]), 3.5, 12.0, 250.0, 6.0, 0.06, 6.0)


def _se3(xi: Array) -> Array:
    """4x4 transform of the twist ``xi`` = (rotation vector [rad], translation [m])."""
    w, v = xi[:3], xi[3:]
    th = float(np.linalg.norm(w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    Rm = np.eye(3) + K if th < 1e-12 else np.eye(3) + math.sin(th) / th * K + (1 - math.cos(th)) / th**2 * K @ K
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rm, v
    return T


@functools.lru_cache(maxsize=16)
def _patch_centres(radius: float, columns: int, row_height: float) -> tuple[Array, Array, NDArray[np.bool_]]:
    """The checker patches' centres in {wm} [m], their outward normals, and which are dark."""
    marker = MarkerModel(radius=radius, columns=columns, row_height=row_height)
    a = np.tile((np.arange(columns) + 0.5) * marker.beta, 2)
    z = np.repeat(0.5 * row_height * np.array([1.0, -1.0]), columns)
    normals = np.column_stack([np.cos(a), np.sin(a), np.zeros(a.size)])
    dark = np.array([marker.is_black(float(ai), float(zi)) for ai, zi in zip(a, z)])
    return np.column_stack([radius * normals[:, :2], z]), normals, dark


def print_is_negative(view: NDArray[np.uint8], camera: StereoCamera, T_left_marker: Array,
                      marker: MarkerModel) -> bool:
    """True where the left ``view`` shows the checker rows' negative at the pose ``T_left_marker``
    (a pose whose roll is known modulo one column puts every dark checker patch on a white one):
    the mean grey level at the centres of the patches the model calls dark, facing the camera,
    is above that of those it calls white."""
    P, normals, dark_all = _patch_centres(float(marker.radius), int(marker.columns), float(marker.row_height))
    R, t = T_left_marker[:3, :3], T_left_marker[:3, 3]
    X = P @ R.T + t
    n = normals @ R.T
    facing = -np.einsum("ij,ij->i", n, X) / np.linalg.norm(X, axis=1) > 0.3
    if not facing.any():
        return False
    uv = np.rint(camera.project_left(X[facing])).astype(int)
    h, w = view.shape[:2]
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    dark = dark_all[facing][inside]
    grey = to_gray(view[uv[inside, 1], uv[inside, 0]][None])[0].astype(float)
    if not dark.any() or dark.all():
        return False
    return bool(grey[dark].mean() > grey[~dark].mean())


def bar_pairs(edges: PrintedEdges, found: EdgeMeasurements) -> tuple[Array, Array, Array, Array, Array, Array]:
    """The measured samples whose partner on the same dark bar was found too, once per bar
    sample: points in {wm} and measured pixels and normals of one boundary (``P_a``, ``uv_a``,
    ``n_a``), then of the other (``P_b``, ``uv_b``, ``n_b``)."""
    pos = np.full(edges.points.shape[0], -1, np.intp)
    pos[found.index] = np.arange(found.index.size)
    a = found.index[(edges.partner[found.index] > found.index) & (pos[edges.partner[found.index]] >= 0)]
    b = edges.partner[a]
    ia, ib = pos[a], pos[b]
    return (edges.points[a], found.uv[ia], found.normal[ia], edges.points[b], found.uv[ib], found.normal[ib])


def _cat(parts: list[Array], empty: tuple[int, ...]) -> Array:
    return np.concatenate(parts) if parts else np.zeros(empty)


def _image_jacobian(K: Array, R_cam: Array, X_cam: Array, X_left: Array) -> Array:
    """d(pixel)/d(twist) (N, 2, 6) of points ``X_cam`` (N, 3) in a camera's frame [m] (``X_left``
    in {ll}) whose rotation from {ll} is ``R_cam``, for a twist (rotation vector, translation) applied in {ll};
    the pinhole part of the projection (distortion changes it by a few percent: Gauss-Newton
    converges to the same fit, the residuals use the full projection)."""
    x, y, z = X_cam[:, 0], X_cam[:, 1], X_cam[:, 2]
    du = np.zeros((X_cam.shape[0], 2, 3))
    du[:, 0, 0], du[:, 0, 2] = K[0, 0] / z, -K[0, 0] * x / z**2
    du[:, 1, 1], du[:, 1, 2] = K[1, 1] / z, -K[1, 1] * y / z**2
    A = du @ R_cam  # d pixel / d X_left
    # d X_left / d twist = [-[X_left]x, I], and a^T (-[X]x) = (X x a)^T
    X = X_left[:, None, :]
    rot = np.stack([X[..., 1] * A[..., 2] - X[..., 2] * A[..., 1], X[..., 2] * A[..., 0] - X[..., 0] * A[..., 2],
                    X[..., 0] * A[..., 1] - X[..., 1] * A[..., 0]], axis=2)
    return np.concatenate([rot, A], axis=2)


Corners = tuple[tuple[Array, Array, Array], tuple[Array, Array, Array]]
Bars = tuple[tuple[Array, ...], tuple[Array, ...]]


def _residuals(camera: StereoCamera, T: Array, corners: Corners, bars: Bars,
               jac: bool) -> tuple[Array, Array, Array, Array]:
    """At the pose ``T`` ({wm} in {ll}): the corner residuals over their noise, the bars' centre
    line residuals [px] and, with ``jac``, their Jacobians for a twist applied in {ll}
    (see :func:`refine_with_edges`)."""
    Rm, tm = T[:3, :3], T[:3, 3]
    R_rl, t_rl = np.asarray(camera.R, float), np.asarray(camera.T, float).reshape(3)
    cams = ((camera.left, np.eye(3), np.zeros(3)), (camera.right, R_rl, t_rl))
    rc, rb, Jc, Jb = [], [], [], []
    for (cam, Rc, tc), (Pc, uvc, sc), (Pa, uva, na, Pb, uvb, nb) in zip(cams, corners, bars):
        XL = np.vstack([Pc, Pa, Pb]) @ Rm.T + tm
        X = XL @ Rc.T + tc
        if not X.shape[0]:
            continue
        q = cam.project(X)
        nc, na_ = Pc.shape[0], Pa.shape[0]
        rc.append(((q[:nc] - uvc) / sc[:, None]).ravel())
        ea = np.einsum("ij,ij->i", q[nc:nc + na_] - uva, na)
        eb = np.einsum("ij,ij->i", q[nc + na_:] - uvb, nb)
        rb.append(0.5 * (ea - eb))
        if jac:
            J = _image_jacobian(np.asarray(cam.K, float), Rc, X, XL)
            Jc.append((J[:nc] / sc[:, None, None]).reshape(-1, 6))
            Jb.append(0.5 * (np.einsum("ij,ijk->ik", na, J[nc:nc + na_])
                             - np.einsum("ij,ijk->ik", nb, J[nc + na_:])))
    return _cat(rc, (0,)), _cat(rb, (0,)), _cat(Jc, (0, 6)), _cat(Jb, (0, 6))


def _bar_weights(rb: Array, bar_sigma_px: float, huber: float) -> Array:
    """Each bar residual's whitening weight: sqrt(2) / ``bar_sigma_px`` (a centre line is the
    mean of two edges), down-weighted beyond ``huber`` sigmas."""
    scale = math.sqrt(2.0) / bar_sigma_px
    return np.sqrt(np.minimum(1.0, huber / np.maximum(np.abs(rb * scale), 1e-12))) * scale


def refine_with_edges(camera: StereoCamera, T_left_marker: Array, corners: Corners, bars: Bars,
                      bar_sigma_px: float, huber: float = 2.0, iterations: int = 1) -> tuple[Array, Array, Array]:
    """The pose {wm} in {ll} that best fits the corners and the dark bars' centre lines of both
    views together, from ``T_left_marker``: ``corners`` per view (points in {wm} (N, 3) [m],
    pixels (N, 2), noise (N,) [px]); ``bars`` per view (:func:`bar_pairs`). A bar's residual is
    half the difference of its two boundaries' distances along their image normals (the shift
    of its centre line: an edge moved by blur, gamma or ink spread moves both boundaries into the
    bar or out of it alike, and cancels, as in an X-corner), over ``bar_sigma_px``, down-weighted
    beyond ``huber`` sigmas. ``iterations`` Gauss-Newton steps on a twist applied in {ll} (at
    least 1). Returns the pose, and at it (to first order in the last step) the corner residuals
    over their noise and the bars' residuals [px] of both views."""
    T = np.asarray(T_left_marker, float).copy()
    rc, rb = np.zeros(0), np.zeros(0)
    for _ in range(iterations):
        rc, rb, Jc, Jb = _residuals(camera, T, corners, bars, True)
        w = _bar_weights(rb, bar_sigma_px, huber)
        J = np.vstack([Jc, w[:, None] * Jb])
        r = np.concatenate([rc, w * rb])
        xi = np.linalg.solve(J.T @ J + 1e-12 * np.eye(6), -J.T @ r)
        T = _se3(xi) @ T
        rc, rb = rc + Jc @ xi, rb + Jb @ xi  # the residuals after the step, to first order
        if np.abs(xi[:3]).max() < 1e-7 and np.abs(xi[3:]).max() < 1e-8:
            break
    return T, rc, rb


def edges_tip_sigma(camera: StereoCamera, T_left_marker: Array, corners: Corners, bars: Bars,
                    bar_sigma_px: float, tips_marker: Array, huber: float = 2.0) -> float:
    """The largest 3D standard deviation [m] of the points ``tips_marker`` (K, 3) in {wm} [m]
    for the pose ``T_left_marker`` ({wm} in {ll}) fitted to the corners at their own noise and
    the bars' centre lines at ``bar_sigma_px`` (down-weighted as in :func:`refine_with_edges`) of
    both views together: first order, from the fit's Jacobian, as
    cvs.tracking.tip_uncertainty.tip_sigma does for the corners alone; inf when they do not
    determine the pose."""
    T = np.asarray(T_left_marker, float)
    _, rb, Jc, Jb = _residuals(camera, T, corners, bars, True)
    J = np.vstack([Jc, _bar_weights(rb, bar_sigma_px, huber)[:, None] * Jb])
    JtJ = J.T @ J
    if J.shape[0] < 6 or not np.all(np.isfinite(JtJ)) or np.linalg.cond(JtJ) > 1e14:
        return float("inf")
    C = np.linalg.inv(JtJ)  # twist covariance: (rotation vector, translation) in {ll}
    worst = 0.0
    for c in np.asarray(tips_marker, float).reshape(-1, 3):
        p = T[:3, :3] @ c + T[:3, 3]
        A = np.hstack([-np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]]), np.eye(3)])
        worst = max(worst, float(np.sqrt(max(np.trace(A @ C @ A.T), 0.0))))
    return worst
