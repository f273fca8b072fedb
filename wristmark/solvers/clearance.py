"""Clearance between arms: their bodies as capsules, surface distances and the QP's velocity damper.

Frames and units: every arm has its own {w} (incision at the origin, the stem along z_w); a
scene of several arms places each {w} in a shared world, so one arm's capsules are brought
into another's {w} by :func:`transformed` with T = T_wA_world @ T_world_wB (4x4, the pose of
B's {w} in A's). Lengths [m], configurations psi [rad, m, ...], rates [rad/s, m/s], dt [s].

The body (:func:`body_capsules`), from the incision to the tip:

- the stem, from the incision (the origin of {w}) to the first base ring {1b}, arm radius;
- each constant-curvature segment as ``per_segment`` chords of its arc, each a capsule of the
  arm radius *plus the chord's sagitta* (L / (2K)) f(theta / (2K)), f = (1 - cos x) / x: the
  chords' capsules then contain the bent tube: a distance is never over-estimated, and
  under-estimated by up to twice the sagitta per arm (0.31 mm at K = 8 on the reference arm's
  100 mm segment bent pi/2; K = 4: 1.2 mm; the count against the error and the cost:
  bench/clearance.py, docs/notes/clearance.md);
- each spacer (rigid link between segments, {(t-1)e} -> {tb}), arm radius;
- the rigid link from the last end ring {Ne} towards the marker sleeve, arm radius;
- the marker sleeve, [wm - h z, wm + h z] along z_wm with the sleeve's radius (4.55 mm, the
  reference marker's; h the sleeve's half length, 2.5 mm: its two checker rows);
- the gripper, from the sleeve's distal end to the tip, as a capsule of the *arm* radius (the
  jaws' 1.8 mm half-width is within it: conservative, and no marker file needed).

A capsule's hemispherical ends make every piece a little longer than the part it models: the
body is covered, never under-estimated, which is what a clearance needs.

The constraint (:func:`clearance_rows`): for a pair of capsules (one of this arm, one of the
other, whose arm is static during the step) at surface distance d with unit normal n (from the
other body towards this one) and this arm's closest axis point p(psi),

    d_dot = n' J_p(psi) psi_dot - dr/dpsi psi_dot >= lo = min(-xi (d - d_s) / dt, 0)

the velocity damper (Faverjon & Tournassoud) with d_s the clearance and xi in (0, 1] the share
of the remaining gap one step may close: linearised, d stays >= d_s. The min(., 0) relaxation:
an arm already inside the clearance (d < d_s) is only forbidden to come closer, never asked
to leave faster than it can (psi_dot = 0 always satisfies every row, so the QP stays feasible).
J_p = (1 - s) J_start + s J_end from the Jacobians of the capsule's end points, which are
forward differences of the body points (one vectorised batch of n + 1 configurations; the
radius's change with the bend, through the sagitta, is differenced alike).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_kinematics import arm_frames, bend_angles, f_g_array
from wristmark.models.arm_shape import ArmShape
from wristmark.models.arm_spec import Arm, ArmSpec, as_spec
from wristmark.models.errors import InputError
from wristmark.models.kinematics import check_psi

Array = NDArray[np.float64]

PER_SEGMENT = 8  # chords (capsules) per constant-curvature segment (bench/clearance.py)
SLEEVE_RADIUS = 0.00455  # [m] the reference marker's sleeve (configs/marker.yaml radius)
SLEEVE_HALF_LENGTH = 0.0025  # [m] the reference sleeve's half length along z_wm (two 2.5 mm rows)
DAMPER_GAIN = 0.5  # xi: share of the gap above the clearance one step may close
INFLUENCE_MARGIN = 0.010  # [m] pairs within clearance + this get a row
MAX_ROWS = 8  # rows per step (the QP is built for this many)
FD_STEP = 1e-7  # [rad, m] forward-difference step of the body points' Jacobian
_PARALLEL = 1e-12  # relative |d1 x d2|^2 below which two segments count as parallel


@dataclass(frozen=True)
class Capsules:
    """Capsules (segments swept by spheres) in one frame [m]: ``start`` and ``end`` (n, 3)
    axis end points, ``radius`` (n,)."""

    start: Array
    end: Array
    radius: Array

    def __post_init__(self) -> None:
        a, b, r = (np.asarray(x, float) for x in (self.start, self.end, self.radius))
        if a.ndim != 2 or a.shape[1] != 3 or b.shape != a.shape or r.shape != (a.shape[0],):
            raise InputError(f"capsules need (n, 3) start and end points and (n,) radii, got "
                             f"{a.shape}, {b.shape}, {r.shape}")
        if not (np.isfinite(a).all() and np.isfinite(b).all() and np.isfinite(r).all()) or (r < 0).any():
            raise InputError("capsules need finite points and radii >= 0")
        object.__setattr__(self, "start", a)
        object.__setattr__(self, "end", b)
        object.__setattr__(self, "radius", r)

    def __len__(self) -> int:
        return int(self.radius.size)

    @staticmethod
    def concat(parts: list[Capsules]) -> Capsules:
        """Several bodies' capsules as one set (e.g. every other arm of a scene)."""
        if not parts:
            return Capsules(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
        return Capsules(np.vstack([p.start for p in parts]), np.vstack([p.end for p in parts]),
                        np.concatenate([p.radius for p in parts]))


def transformed(caps: Capsules, T: Array) -> Capsules:
    """``caps`` moved by the 4x4 rigid transform ``T`` (the pose of their frame in the target
    frame: e.g. arm B's {w} in arm A's {w}); radii unchanged."""
    T = np.asarray(T, float)
    if T.shape != (4, 4):
        raise InputError(f"T must be 4x4, got {T.shape}")
    R, t = T[:3, :3], T[:3, 3]
    return Capsules(caps.start @ R.T + t, caps.end @ R.T + t, caps.radius.copy())


@dataclass(frozen=True)
class _Layout:
    """The body's capsules as index pairs into the body points of :func:`_body_points`."""

    i0: NDArray[np.int_]
    i1: NDArray[np.int_]
    radius: Array  # base radius per capsule [m]
    sagitta_of: NDArray[np.int_]  # per capsule: the segment whose sagitta inflates it, -1: none
    extent: float  # [m] the body's reach from {1b} along the centreline plus its largest radius and sagitta


_LAYOUTS: dict[tuple[ArmSpec, int, float, float, float | None], _Layout] = {}


def _layout(spec: ArmSpec, per_segment: int, sleeve_radius: float, sleeve_half_length: float,
            tip_radius: float | None) -> _Layout:
    key = (spec, per_segment, sleeve_radius, sleeve_half_length, tip_radius)
    lay = _LAYOUTS.get(key)
    if lay is None:
        if len(_LAYOUTS) > 64:
            _LAYOUTS.clear()
        lay = _LAYOUTS[key] = _make_layout(*key)
    return lay


def _make_layout(spec: ArmSpec, per_segment: int, sleeve_radius: float, sleeve_half_length: float,
                 tip_radius: float | None) -> _Layout:
    r = spec.outer_diameter / 2.0
    K = per_segment
    i0: list[int] = []
    i1: list[int] = []
    rad: list[float] = []
    sag: list[int] = []

    def add(a: int, b: int, radius: float, seg: int = -1) -> None:
        i0.append(a)
        i1.append(b)
        rad.append(radius)
        sag.append(seg)

    # points: 0 the origin; per segment t: base (1 + t (K + 1)), then K arc points; then the link's
    # end, the sleeve's distal end and the tip
    add(0, 1, r)  # stem
    for t in range(len(spec.segments)):
        base = 1 + t * (K + 1)
        if t > 0 and spec.segments[t].spacer > 0:
            add(base - 1, base, r)  # spacer: previous end ring -> this base ring
        for k in range(K):
            add(base + k, base + k + 1, r, t)
    end = 1 + len(spec.segments) * (K + 1) - 1
    link, sleeve, tip = end + 1, end + 2, end + 3
    if spec.marker_offset > sleeve_half_length:
        add(end, link, r)
    add(link, sleeve, sleeve_radius)
    add(sleeve, tip, r if tip_radius is None else tip_radius)
    lengths = [seg.length for seg in spec.segments]
    along = sum(lengths) + sum(seg.spacer for seg in spec.segments) + spec.marker_offset + sleeve_half_length \
        + max(spec.tip_offset, sleeve_half_length)
    extent = along + max(rad) + max(lengths) / 4.0  # a chord's sagitta is below its arc's length / 4
    return _Layout(np.array(i0), np.array(i1), np.array(rad), np.array(sag), extent)


def _body_points(spec: ArmSpec, Q: Array, K: int, h: float) -> tuple[Array, Array]:
    """Body points (B, P, 3) in {w} [m] for configurations Q (B, n) and each segment's chord
    sagitta (B, N) [m]."""
    poses = arm_frames(spec, Q)
    th, de = bend_angles(spec, Q)  # (B, N)
    B, N = th.shape
    lengths = spec.layout.lengths
    s = np.arange(1, K + 1) / K  # (K,)
    # bend up to each arc point (B, N, K), and half a chord's bend (the sagitta's), in one call
    f_all, g, _, _ = f_g_array(th[..., None] * np.append(s, 0.5 / K))
    f, g, fs = f_all[..., :K], g[..., :K], f_all[..., K]
    c, sn = np.cos(de)[..., None], np.sin(de)[..., None]
    Ls = lengths[:, None] * s  # (N, K)
    local = np.stack([Ls * c * f, -Ls * sn * f, Ls * g], -1)  # (B, N, K, 3) in {tb}
    Rb = poses.T_world_base[..., :3, :3]  # (B, N, 3, 3)
    pb = poses.T_world_base[..., :3, 3]  # (B, N, 3)
    arc = np.einsum("bnij,bnkj->bnki", Rb, local) + pb[:, :, None, :]
    seg = np.concatenate([pb[:, :, None, :], arc], 2).reshape(B, N * (K + 1), 3)
    Tm = poses.T_world_marker
    z, wm = Tm[..., :3, 2], Tm[..., :3, 3]
    end = poses.T_world_end[:, -1, :3, 3]
    link = end + max(spec.marker_offset - h, 0.0) * z
    pts = np.concatenate([np.zeros((B, 1, 3)), seg, link[:, None], (wm + h * z)[:, None],
                          poses.T_world_tip[:, None, :3, 3]], 1)
    return pts, lengths / (2 * K) * np.abs(fs)  # f is odd: a planar segment bends either way


def _capsules_batch(spec: ArmSpec, Q: Array, lay: _Layout, K: int, h: float) -> tuple[Array, Array, Array]:
    """(start (B, C, 3), end (B, C, 3), radius (B, C)) for configurations Q (B, n)."""
    pts, sag = _body_points(spec, Q, K, h)
    on = lay.sagitta_of >= 0
    rad = np.broadcast_to(lay.radius, (Q.shape[0], lay.radius.size)).copy()
    rad[:, on] += sag[:, lay.sagitta_of[on]]
    return pts[:, lay.i0], pts[:, lay.i1], rad


def _prepare(params: Arm, psi: object, per_segment: int, sleeve_radius: float, sleeve_half_length: float,
             tip_radius: float | None) -> tuple[ArmSpec, Array, _Layout]:
    if per_segment < 1:
        raise InputError(f"per_segment must be >= 1, got {per_segment}")
    spec = as_spec(params)
    q = check_psi(psi, params)
    return spec, q, _layout(spec, per_segment, sleeve_radius, sleeve_half_length, tip_radius)


def body_capsules(params: Arm, psi: object, per_segment: int = PER_SEGMENT, sleeve_radius: float = SLEEVE_RADIUS,
                  sleeve_half_length: float = SLEEVE_HALF_LENGTH, tip_radius: float | None = None) -> Capsules:
    """The arm's body at ``psi`` as capsules in its {w} [m], from the incision to the tip (the
    module docstring lists them): stem, ``per_segment`` chords per segment (radius inflated by
    the chord's sagitta), spacers, rigid link, marker sleeve (``sleeve_radius``, half length
    ``sleeve_half_length`` about {wm} along z_wm) and gripper to the tip (``tip_radius``, None:
    the arm's radius). Any arm (the reference arm's flat parameters or an ArmSpec)."""
    spec, q, lay = _prepare(params, psi, per_segment, sleeve_radius, sleeve_half_length, tip_radius)
    a, b, r = _capsules_batch(spec, q[None], lay, per_segment, sleeve_half_length)
    return Capsules(a[0], b[0], r[0])


def shape_capsules(shape: ArmShape, sleeve_radius: float = SLEEVE_RADIUS,
                   sleeve_half_length: float = SLEEVE_HALF_LENGTH) -> Capsules:
    """A body already computed (an :class:`models.arm_shape.ArmShape`, e.g. a simulated true
    arm's, which no psi describes) as capsules in its frame [m]: one per step of its centreline
    (arm radius), the rigid link from the last end ring to the sleeve, the sleeve (as
    :func:`body_capsules`) and the gripper to the tip (arm radius)."""
    C = np.asarray(shape.centreline, float)
    z, o = shape.T_world_marker[:3, 2], shape.T_world_marker[:3, 3]
    lo, hi = o - sleeve_half_length * z, o + sleeve_half_length * z
    end = np.asarray(shape.frames.T_world_2e[:3, 3], float)
    start = np.vstack([C[:-1], end, lo, hi])
    stop = np.vstack([C[1:], lo, hi, np.asarray(shape.tip, float)])
    r = np.full(len(start), float(shape.radius))
    r[-2] = sleeve_radius
    return Capsules(start, stop, r)


def segment_closest(p1: Array, q1: Array, p2: Array, q2: Array) -> tuple[Array, Array, Array, Array]:
    """Closest points between segments [p1, q1] and [p2, q2] (arrays (..., 3), broadcast):
    parameters s, t in [0, 1] (...,) and the points c1 = p1 + s (q1 - p1), c2 = p2 + t (q2 - p2).
    Robust for parallel segments (one of the closest pairs) and for segments of zero length
    (points); Ericson, Real-Time Collision Detection, 5.1.9, vectorised."""
    p1, q1, p2, q2 = (np.asarray(v, float) for v in (p1, q1, p2, q2))
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    f = np.einsum("...i,...i->...", d2, r)
    c = np.einsum("...i,...i->...", d1, r)
    b = np.einsum("...i,...i->...", d1, d2)
    denom = a * e - b * b
    pa, pe = a > 0.0, e > 0.0
    a_s = np.where(pa, a, 1.0)
    e_s = np.where(pe, e, 1.0)
    general = denom > _PARALLEL * a * e
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(general, np.clip((b * f - c * e) / np.where(general, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0.0, np.clip(-c / a_s, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_s, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate: the first a point (s = 0, t its projection), the second a point (t = 0), both
    s = np.where(pa, s, 0.0)
    t = np.where(pa, t, np.clip(f / e_s, 0.0, 1.0))
    s = np.where(pe | ~pa, s, np.clip(-c / a_s, 0.0, 1.0))
    t = np.where(pe, t, 0.0)
    return s, t, p1 + s[..., None] * d1, p2 + t[..., None] * d2


def _normals(ca: Array, cb: Array, da: Array, db: Array) -> tuple[Array, Array]:
    """Centre distances (...,) and unit normals from cb towards ca (..., 3); where the axes meet,
    the normal is perpendicular to both axes (or to the first, or x_w)."""
    v = ca - cb
    dist = np.linalg.norm(v, axis=-1)
    n = v / np.where(dist > 0.0, dist, 1.0)[..., None]
    bad = dist <= 1e-12
    if bad.any():
        for idx in zip(*np.nonzero(bad)):
            w = np.cross(da[idx], db[idx])
            if np.linalg.norm(w) < 1e-12 * (1.0 + np.linalg.norm(da[idx]) * np.linalg.norm(db[idx])):
                w = np.cross(da[idx], [1.0, 0.0, 0.0]) if abs(da[idx][0]) < 0.9 * np.linalg.norm(da[idx]) \
                    else np.cross(da[idx], [0.0, 1.0, 0.0])
            nw = np.linalg.norm(w)
            n[idx] = w / nw if nw > 0 else np.array([1.0, 0.0, 0.0])
    return dist, n


def _pairs(a: Capsules, b: Capsules) -> tuple[Array, Array, Array, Array, Array]:
    """All pairs: surface distances (na, nb), this side's axis parameter s (na, nb), the closest
    axis points on a and b (na, nb, 3) and unit normals from b towards a (na, nb, 3)."""
    return _pairs_of(a.start, a.end, a.radius, b)


def _pairs_of(sa: Array, ea: Array, ra: Array, b: Capsules) -> tuple[Array, Array, Array, Array, Array]:
    pa, qa = sa[:, None], ea[:, None]
    pb, qb = b.start[None], b.end[None]
    s, _, ca, cb = segment_closest(pa, qa, pb, qb)
    ca, cb = np.broadcast_to(ca, s.shape + (3,)), np.broadcast_to(cb, s.shape + (3,))
    dist, n = _normals(ca, cb, np.broadcast_to(qa - pa, ca.shape), np.broadcast_to(qb - pb, cb.shape))
    return dist - ra[:, None] - b.radius[None], s, ca, cb, n


def min_distance(a: Capsules, b: Capsules) -> tuple[float, Array, Array, int, int]:
    """Least surface distance between two sets of capsules in one frame [m] (centre distance
    minus radii; negative when they overlap), the points on a's and b's surfaces along the
    pair's normal (a's nearest b and b's nearest a; overlapping, they cross) and the pair's
    indices (into a, into b). Empty sets: (inf, nan points, -1, -1)."""
    if len(a) == 0 or len(b) == 0:
        nan = np.full(3, np.nan)
        return math.inf, nan, nan.copy(), -1, -1
    d, _, ca, cb, n = _pairs(a, b)
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return float(d[i, j]), ca[i, j] - a.radius[i] * n[i, j], cb[i, j] + b.radius[j] * n[i, j], int(i), int(j)


def _beyond_reach(spec: ArmSpec, q: Array, lay: _Layout, others: Capsules, reach: float) -> bool:
    """True when every other capsule is farther than ``reach`` [m] from the sphere about the
    origin of {w} that holds this arm's whole body (the stem's feed plus the body's length along
    the centreline, its largest radius and sagitta): no row can be made, and the body need not be
    evaluated."""
    pri = spec.layout.prismatic_list
    body = abs(sum(float(q[i]) for i in pri)) + lay.extent
    a, d = others.start, others.end - others.start
    dd = np.einsum("ij,ij->i", d, d)
    t = np.clip(-np.einsum("ij,ij->i", a, d) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
    gap = np.linalg.norm(a + t[:, None] * d, axis=1) - others.radius - body
    return bool(gap.min() > reach)


def clearance_rows(params: Arm, psi: object, others: Capsules, clearance_m: float, dt: float,
                   xi: float = DAMPER_GAIN, influence_m: float | None = None, m_max: int = MAX_ROWS,
                   per_segment: int = PER_SEGMENT, sleeve_radius: float = SLEEVE_RADIUS,
                   sleeve_half_length: float = SLEEVE_HALF_LENGTH,
                   tip_radius: float | None = None) -> tuple[Array, Array]:
    """Velocity-damper rows ``lo <= A psi_dot`` (A (k, n), lo (k,), k <= ``m_max``) that keep
    this arm's body at least ``clearance_m`` [m] from the capsules ``others`` (static, in this
    arm's {w}) over a step of ``dt`` [s] (the module docstring's formula, with the relaxation
    lo <= 0). Rows: for each of this arm's capsules its nearest other capsule, when within
    ``influence_m`` [m] (None: clearance + INFLUENCE_MARGIN), the nearest ``m_max`` of them.
    Cost: one vectorised body evaluation of n + 1 configurations (psi and the forward
    differences) and the all-pairs distances (docs/notes/clearance.md)."""
    if not 0.0 < xi <= 1.0:
        raise InputError(f"xi must be in (0, 1], got {xi}")
    if clearance_m < 0.0 or dt <= 0.0:
        raise InputError(f"clearance must be >= 0 and dt > 0, got {clearance_m} m and {dt} s")
    spec, q, lay = _prepare(params, psi, per_segment, sleeve_radius, sleeve_half_length, tip_radius)
    n = q.size
    empty = np.zeros((0, n)), np.zeros(0)
    if len(others) == 0 or m_max < 1:
        return empty
    reach = clearance_m + INFLUENCE_MARGIN if influence_m is None else influence_m
    if _beyond_reach(spec, q, lay, others, reach):
        return empty
    # the body at psi and at psi + FD_STEP e_i (the forward differences), in one batch
    a, b, r = _capsules_batch(spec, np.vstack([q, q + FD_STEP * np.eye(n)]), lay, per_segment, sleeve_half_length)
    d, s, _, _, nrm = _pairs_of(a[0], b[0], r[0], others)
    j = np.argmin(d, axis=1)
    dj = d[np.arange(d.shape[0]), j]
    sel = np.nonzero(dj < reach)[0]
    if sel.size == 0:
        return empty
    sel = sel[np.argsort(dj[sel], kind="stable")][:m_max]
    Ja = (a[1:, sel] - a[0, sel]) / FD_STEP  # (n, k, 3): d start / d psi_i
    Jb = (b[1:, sel] - b[0, sel]) / FD_STEP
    Jr = (r[1:, sel] - r[0, sel]) / FD_STEP  # (n, k)
    dj = dj[sel]
    sk = s[sel, j[sel]]
    Jp = (1.0 - sk)[None, :, None] * Ja + sk[None, :, None] * Jb  # (n, k, 3)
    nk = nrm[sel, j[sel]]  # (k, 3)
    A = np.einsum("ikc,kc->ki", Jp, nk) - Jr.T
    lo = np.minimum(-xi * (dj - clearance_m) / dt, 0.0)
    return A, lo
