"""Actuation map of any arm (models.arm_spec): psi <-> actuator coordinates, and its Jacobian.

Actuators, in order: the stem joints as they are [rad or m], then each segment's actuators in
the order of its ``angles`` sigma_k (in {tb}, from x_tb towards y_tb). With the bend written as
the vector x_t = theta_t cos(delta_t), y_t = theta_t sin(delta_t) (delta_t the fixed plane of
a planar segment), a pull displacement [m] (positive when the box retracts the backbone or
tendon) is linear in (x, y):

    push_pull (decoupled): s_k = r theta_t cos(delta_t + sigma_k) = r (x_t cos sigma_k - y_t sin sigma_k)
    tendons (coupled):     s_k = r sum_{j <= t} theta_j cos(delta_j + sigma_k)   (r, sigma_k of segment t)
    direct:                the box takes theta_t, delta_t (theta_t alone if planar) [rad]

so the pull actuators are a = M [x_1, y_1, ..., x_N, y_N] with a constant matrix M. For the
reference arm (angles [0, pi/2]) this is models.actuation: s_ta = r theta cos(delta),
s_tb = -r theta sin(delta). Inverse, proximal segment first: remove the coupling of the segments
already recovered, then least squares over the segment's own actuators (exact for push_pull and
direct, the best fit for tendons whose lengths disagree); theta = hypot(x, y), delta =
atan2(y, x) (signed theta = the projection on the plane if planar). At theta = 0 delta is taken
from a hint. psi and actuators may carry leading batch axes. Units SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_kinematics import bend_angles, check_arm_psi
from wristmark.models.arm_spec import ArmSpec
from wristmark.models.errors import InputError

Array = NDArray[np.float64]
Index = NDArray[np.int_]

_EXACT_ZERO = 1e-15  # |cos|, |sin| of an actuator angle below this is 0 (pi/2 in floats has cos 6e-17)


@dataclass(frozen=True, eq=False)
class _Maps:
    """The constant parts of one arm's actuation map (see the module doc)."""

    M: Array  # (m, 2N): pull actuators from [x_1, y_1, ..., x_N, y_N]; zero rows elsewhere
    copy_psi: Index  # psi indices copied to actuators (stem joints, direct segments)
    copy_act: Index  # ... and the actuator indices they land on
    segments: tuple[tuple[str, slice, int, int, float, Array], ...]  # kind, rows, theta idx, delta idx|-1, plane, solve


def _maps(spec: ArmSpec) -> _Maps:
    cache = spec.__dict__.setdefault("_derived", {})  # per-instance cache on the frozen dataclass
    if "actuation" not in cache:
        cache["actuation"] = _build(spec)
    return cache["actuation"]  # type: ignore[no-any-return]


def _build(spec: ArmSpec) -> _Maps:
    N = len(spec.segments)
    M = np.zeros((spec.m, 2 * N))
    copy_psi = list(range(len(spec.stem)))
    copy_act = list(range(len(spec.stem)))
    segs = []
    row = len(spec.stem)
    for t, (seg, ti, di) in enumerate(zip(spec.segments, spec.theta_index, spec.delta_index)):
        rows = slice(row, row + seg.actuators)
        plane = seg.planar if seg.planar is not None else 0.0
        kind = seg.actuation.type
        solve = np.zeros((0, 0))
        if kind == "direct":
            copy_psi += [ti] + ([di] if di is not None else [])
            copy_act += list(range(rows.start, rows.stop))
        else:
            sig = np.array(seg.actuation.angles)
            cols = np.stack([np.cos(sig), -np.sin(sig)], -1)
            cols[np.abs(cols) < _EXACT_ZERO] = 0.0  # right angles exactly: [0, pi/2] gives s_b = -r theta sin(delta)
            cols *= seg.actuation.pitch_radius  # (k, 2)
            first = 0 if kind == "tendons" else t
            for j in range(first, t + 1):
                M[rows, 2 * j : 2 * j + 2] = cols
            own = cols if seg.planar is None else cols @ np.array([[math.cos(plane)], [math.sin(plane)]])
            solve = np.linalg.pinv(own)  # (2, k) or (1, k): least squares over the segment's actuators
        segs.append((kind, rows, ti, -1 if di is None else di, plane, solve))
        row = rows.stop
    return _Maps(M, np.array(copy_psi, int), np.array(copy_act, int), tuple(segs))


def _bend_vectors(spec: ArmSpec, q: Array) -> tuple[Array, Array, Array]:
    """theta, delta (..., N) and the bend vectors [x_1, y_1, ...] (..., 2N) of psi."""
    th, de = bend_angles(spec, q)
    xy = np.stack([th * np.cos(de), th * np.sin(de)], -1).reshape(*th.shape[:-1], 2 * th.shape[-1])
    return th, de, xy


def arm_actuators(spec: ArmSpec, psi: object) -> Array:
    """Actuator coordinates (m,) of configuration ``psi`` (n,): the stem joints [rad or m], then
    per segment its pull displacements [m] or, if direct, theta (and delta) [rad]. A batch of psi
    (..., n) gives (..., m)."""
    q = check_arm_psi(spec, psi)
    mp = _maps(spec)
    _, _, xy = _bend_vectors(spec, q)
    a = xy @ mp.M.T
    a[..., mp.copy_act] = q[..., mp.copy_psi]
    return a


def arm_actuator_jacobian(spec: ArmSpec, psi: object) -> Array:
    """d(actuators)/d(psi), shape (m, n) at ``psi`` (n,) ((..., m, n) for a batch): rows follow
    the actuators [m or rad], columns follow psi."""
    q = check_arm_psi(spec, psi)
    mp = _maps(spec)
    th, de, _ = _bend_vectors(spec, q)
    c, s = np.cos(de), np.sin(de)
    N = th.shape[-1]
    D = np.zeros((*q.shape[:-1], 2 * N, spec.n))  # d[x, y]/d psi
    lay = spec.layout
    seg = np.arange(N)
    D[..., 2 * seg, lay.theta_index] = c
    D[..., 2 * seg + 1, lay.theta_index] = s
    b = lay.bending
    D[..., 2 * b, lay.bending_delta_index] = -(th * s)[..., b]
    D[..., 2 * b + 1, lay.bending_delta_index] = (th * c)[..., b]
    J = mp.M @ D
    J[..., mp.copy_act, mp.copy_psi] = 1.0
    return J


def arm_psi_from_actuators(spec: ArmSpec, actuators: object, delta_hint: object = None) -> Array:
    """Configuration psi (n,) [rad or m] from actuator coordinates (m,) (batches: (..., m)).

    Exact for push_pull and direct segments; tendons: least squares over the segment's tendons
    after removing the proximal segments' coupling (proximal first). theta >= 0 and delta in
    (-pi, pi] (a planar theta is signed); where theta = 0, delta is ``delta_hint``'s (a psi of
    the same arm, e.g. the last configuration), else 0."""
    a = np.asarray(actuators, dtype=float)
    if a.ndim == 0 or a.shape[-1] != spec.m:
        raise InputError(f"actuators must have {spec.m} entries [{', '.join(spec.actuator_names)}], "
                         f"got shape {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(f"actuators must be finite, got {a.tolist()}")
    hint = check_arm_psi(spec, delta_hint) if delta_hint is not None else None
    mp = _maps(spec)
    lead = a.shape[:-1]
    q = np.zeros((*lead, spec.n))
    q[..., mp.copy_psi] = a[..., mp.copy_act]
    xy = np.zeros((*lead, 2 * len(spec.segments)))
    for t, (kind, rows, ti, di, plane, solve) in enumerate(mp.segments):
        if kind == "direct":
            delta = q[..., di] if di >= 0 else plane
            xy[..., 2 * t], xy[..., 2 * t + 1] = q[..., ti] * np.cos(delta), q[..., ti] * np.sin(delta)
            continue
        own = a[..., rows] - xy[..., : 2 * t] @ mp.M[rows, : 2 * t].T  # proximal coupling removed
        sol = own @ solve.T
        if di < 0:  # planar: signed theta along the fixed plane
            q[..., ti] = sol[..., 0]
            xy[..., 2 * t], xy[..., 2 * t + 1] = sol[..., 0] * math.cos(plane), sol[..., 0] * math.sin(plane)
            continue
        x, y = sol[..., 0], sol[..., 1]
        xy[..., 2 * t], xy[..., 2 * t + 1] = x, y
        theta = np.hypot(x, y)
        fallback = hint[..., di] if hint is not None else 0.0
        q[..., ti] = theta
        q[..., di] = np.where(theta > 0.0, np.arctan2(y, x), fallback)
    return q
