"""Closed-form kinematics of any arm (models.arm_spec): frames in {w} and the 6 x n tip Jacobian.

Chain: {w} -> stem joints (revolute_z: Rz(q), prismatic_z: Tz(q), in order) -> {1b} -> seg 1 ->
{1e} -> Tz(spacer_2) -> {2b} -> ... -> {Ne} -> Tz(marker_offset) -> {wm} -> Tz(tip_offset) -> tip,
each segment {tb} -> {te} by models.constant_curvature's formulas (R = Rz(-delta) Ry(theta)
Rz(delta), p = L [cos(delta) f, -sin(delta) f, g]); a planar segment's delta is its fixed
``planar`` angle. Every stem joint acts along or about the z axis of {w} (each keeps that axis),
so a revolute column of the Jacobian is [-y_tip, x_tip, 0, 0, 0, 1] and a prismatic one
[0, 0, 1, 0, 0, 0], whatever their order. For the reference arm (ArmSpec.from_params) this is
models.kinematics' chain: one configuration's frames and Jacobian are its numbers bit for bit,
a batch's agree to ~1e-16 (tests/models/test_arm_kinematics.py).

Two evaluations of the same formulas: one configuration (psi of shape (n,), the controller's
hot path) runs on plain Python floats segment by segment with models.kinematics' helpers, as
today's reference chain does (numpy calls on 3x3 arrays cost more than the arithmetic; for the
reference arm the numbers are then models.kinematics'); a batch (psi of shape
(..., n) with leading axes) is vectorised with numpy: all segments and configurations at once, the
chain in one 4x4 product per segment. Both agree to ~1e-16 (tests). Units SI: [m], [rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import ArmSpec
from wristmark.models.constant_curvature import Rot, Vec, segment_pose
from wristmark.models.errors import InputError

# the reference chain's float helpers, shared so the two chains compute alike
from wristmark.models.float_chain import _along_z, _compose, _homogeneous_stack, _segment_columns

Array = NDArray[np.float64]

_SERIES_BELOW = 0.2  # [rad], as models.constant_curvature.f_g
_POWERS = np.arange(6.0)
# Taylor coefficients in u = theta^2 of f/theta, g, f', g'/theta (models.constant_curvature.f_g)
_COEF = np.array([
    [1 / 2, -1 / 24, 1 / 720, -1 / 40320, 1 / 3628800, -1 / 479001600],
    [1, -1 / 6, 1 / 120, -1 / 5040, 1 / 362880, -1 / 39916800],
    [1 / 2, -1 / 8, 1 / 144, -1 / 5760, 1 / 403200, -1 / 43545600],
    [-1 / 3, 1 / 30, -1 / 840, 1 / 45360, -1 / 3991680, 1 / 518918400],
]).T


def check_arm_psi(spec: ArmSpec, psi: object) -> Array:
    """psi as a finite float array of shape (..., n); raise InputError otherwise."""
    q = np.asarray(psi, dtype=float)
    if q.ndim == 0 or q.shape[-1] != spec.n:
        raise InputError(f"psi must have {spec.n} entries [{', '.join(spec.names)}], got shape {q.shape}")
    if not (all(map(math.isfinite, q.tolist())) if q.ndim == 1 else np.isfinite(q).all()):
        raise InputError(f"psi must be finite, got {q.tolist()}")
    return q


def f_g_array(theta: Array) -> tuple[Array, Array, Array, Array]:
    """Element-wise f = (1-cos t)/t, g = sin t/t and their derivatives f', g' (smooth at t = 0;
    the forms and series of models.constant_curvature.f_g)."""
    small = np.abs(theta) < _SERIES_BELOW
    ts = np.where(small, 1.0, theta) if small.any() else theta
    sh = np.sin(0.5 * theta)
    S = np.sin(theta)
    f = 2.0 * sh * sh / ts
    g = S / ts
    df = (S - f) / ts
    dg = (np.cos(theta) - g) / ts
    if ts is not theta:
        ser = (theta[..., None] ** 2) ** _POWERS @ _COEF  # (..., 4): f/t, g, f', g'/t
        f = np.where(small, theta * ser[..., 0], f)
        g = np.where(small, ser[..., 1], g)
        df = np.where(small, ser[..., 2], df)
        dg = np.where(small, theta * ser[..., 3], dg)
    return f, g, df, dg


@dataclass(frozen=True)
class ArmPoses:
    """Poses in {w} of any arm's frames for one configuration, or a batch (leading axes) [m].

    ``T_world_base[..., t]`` / ``T_world_end[..., t]`` are segment t+1's base ring {tb} and end
    ring {te} (4x4 each); ``T_world_marker`` is {wm}, ``T_world_tip`` the tip frame.
    """

    T_world_base: Array
    T_world_end: Array
    T_world_marker: Array
    T_world_tip: Array
    _segments: tuple[Array, ...] = field(default=(), repr=False, compare=False)  # batch: per-segment terms
    _chain: tuple[tuple[Rot, Vec], ...] = field(default=(), repr=False, compare=False)  # one psi: float poses

    @property
    def tip(self) -> Array:
        """Tip position in {w} [m]."""
        return self.T_world_tip[..., :3, 3]


def bend_angles(spec: ArmSpec, q: Array) -> tuple[Array, Array]:
    """Each segment's theta and delta [rad] from psi ``q`` (..., n), shape (..., N) each; a planar
    segment's delta is its fixed plane."""
    lay = spec.layout
    if lay.planar_values.size:
        q = np.concatenate([q, np.broadcast_to(lay.planar_values, (*q.shape[:-1], lay.planar_values.size))], -1)
    return q[..., lay.theta_index], q[..., lay.delta_index]


def _float_chain(spec: ArmSpec, q: list[float]) -> tuple[tuple[Rot, Vec], ...]:
    """Float poses in {w} of {1b}, {1e}, ..., {Nb}, {Ne}, {wm}, tip (see kinematics._compose)."""
    lay = spec.layout
    rev, pri = lay.revolute_list, lay.prismatic_list
    phi = q[rev[0]] if len(rev) == 1 else sum(q[i] for i in rev)  # one joint: its value as is (-0.0 stays)
    c, s = math.cos(phi), math.sin(phi)
    R: Rot = (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    p: Vec = (0.0, 0.0, q[pri[0]] if len(pri) == 1 else sum(q[i] for i in pri))
    out: list[tuple[Rot, Vec]] = []
    for length, spacer, ti, di, plane in lay.terms:
        if out:
            p = _along_z(R, p, spacer)
        out.append((R, p))
        R, p = _compose(R, p, *segment_pose(length, q[ti], plane if di < 0 else q[di]))
        out.append((R, p))
    pm = _along_z(R, p, spec.marker_offset)
    out += [(R, pm), (R, _along_z(R, pm, spec.tip_offset))]
    return tuple(out)


def arm_frames(spec: ArmSpec, psi: object) -> ArmPoses:
    """All frames of ``spec``'s chain in {w} [m] at configuration ``psi`` (shape (n,), or
    (..., n) for a batch)."""
    q = check_arm_psi(spec, psi)
    if q.ndim == 1:
        chain = _float_chain(spec, q.tolist())
        T = _homogeneous_stack(list(chain))
        return ArmPoses(T[0:-2:2], T[1:-2:2], T[-2], T[-1], _chain=chain)
    return _batch_frames(spec, q)


def _batch_frames(spec: ArmSpec, q: Array) -> ArmPoses:
    """arm_frames for psi of shape (..., n), vectorised over the batch and the segments."""
    lay = spec.layout
    th, de = bend_angles(spec, q)
    f, g, df, dg = f_g_array(th)
    c, s = np.cos(de), np.sin(de)
    S = np.sin(th)
    C = np.cos(th)
    v = th * f  # 1 - cos(theta) without cancellation
    csv = c * s * v
    L = lay.lengths
    one, zero = np.ones_like(th), np.zeros_like(th)
    # local poses Tz(spacer_t) * T_{tb}^{te}, shape (..., N, 4, 4)
    local = np.stack([1.0 - c * c * v, csv, c * S, L * c * f,
                      csv, 1.0 - s * s * v, -s * S, -L * s * f,
                      -S * c, S * s, C, L * g + lay.spacers,
                      zero, zero, zero, one], -1).reshape(*th.shape, 4, 4)
    phi = q[..., lay.revolute].sum(-1)
    cp, sp = np.cos(phi), np.sin(phi)
    z0, o0 = np.zeros_like(phi), np.ones_like(phi)
    prev = np.stack([cp, -sp, z0, z0, sp, cp, z0, z0, z0, z0, o0, q[..., lay.prismatic].sum(-1),
                     z0, z0, z0, o0], -1).reshape(*phi.shape, 4, 4)
    ends = np.empty_like(local)
    bases = np.empty_like(local)
    for t in range(local.shape[-3]):
        bases[..., t, :, :] = prev
        prev = prev @ local[..., t, :, :]
        ends[..., t, :, :] = prev
    bases[..., :3, 3] += bases[..., :3, 2] * lay.spacers[:, None]  # {tb} = {(t-1)e} Tz(spacer_t)
    marker = prev.copy()
    marker[..., :3, 3] += prev[..., :3, 2] * spec.marker_offset
    tip = marker.copy()
    tip[..., :3, 3] += prev[..., :3, 2] * spec.tip_offset
    return ArmPoses(bases, ends, marker, tip, (th, f, g, df, dg, c, s, S))


def arm_tip_jacobian(spec: ArmSpec, psi: object, poses: ArmPoses | None = None) -> Array:
    """6 x n Jacobian at ``psi``: rows 0-2 tip linear velocity [m/s], rows 3-5 tip-frame angular
    velocity [rad/s], both in {w}; columns follow psi_dot (spec.names). A batch of psi (..., n)
    gives (..., 6, n). ``poses`` (:func:`arm_frames` at the same psi) saves recomputing the chain."""
    q = check_arm_psi(spec, psi)
    if q.ndim == 1:
        chain = poses._chain if poses is not None and poses._chain else _float_chain(spec, q.tolist())
        return _float_jacobian(spec, q.tolist(), chain)
    if poses is None or not poses._segments:
        poses = _batch_frames(spec, q)
    lay = spec.layout
    th, f, g, df, dg, c, s, S = poses._segments
    L = lay.lengths
    zero = np.zeros_like(th)
    # local (base-frame) columns [d/dtheta, d/ddelta] of {te}'s origin and frame: (..., N, 3, 2)
    Jv = np.stack([L * c * df, -L * s * f, -L * s * df, -L * c * f, L * dg, zero], -1).reshape(*th.shape, 3, 2)
    Jw = np.stack([s, c * S, c, -s * S, zero, -th * f], -1).reshape(*th.shape, 3, 2)
    Rb = poses.T_world_base[..., :3, :3]
    W = Rb @ Jw
    V = Rb @ Jv
    ptip = poses.tip
    lever = ptip[..., None, :] - poses.T_world_end[..., :3, 3]  # (..., N, 3)
    lx, ly, lz = (lever[..., i, None] for i in range(3))
    wx, wy, wz = W[..., 0, :], W[..., 1, :], W[..., 2, :]
    V[..., 0, :] += wy * lz - wz * ly
    V[..., 1, :] += wz * lx - wx * lz
    V[..., 2, :] += wx * ly - wy * lx
    J = np.zeros((*th.shape[:-1], 6, spec.n))
    VW = np.concatenate([V, W], -2)  # (..., N, 6, 2)
    J[..., lay.theta_index] = np.swapaxes(VW[..., 0], -1, -2)
    if lay.bending.size:
        J[..., lay.bending_delta_index] = np.swapaxes(VW[..., 1][..., lay.bending, :], -1, -2)
    if lay.revolute.size:
        J[..., 0, lay.revolute] = -ptip[..., 1, None]
        J[..., 1, lay.revolute] = ptip[..., 0, None]
        J[..., 5, lay.revolute] = 1.0
    J[..., 2, lay.prismatic] = 1.0
    return J


def _float_jacobian(spec: ArmSpec, q: list[float], chain: tuple[tuple[Rot, Vec], ...]) -> Array:
    """6 x n tip Jacobian of one configuration from its float chain (see arm_tip_jacobian)."""
    n = spec.n
    ptip = chain[-1][1]
    J = [0.0] * (6 * n)
    lay = spec.layout
    for i in lay.revolute_list:
        J[i], J[n + i], J[5 * n + i] = -ptip[1], ptip[0], 1.0
    for i in lay.prismatic_list:
        J[2 * n + i] = 1.0
    for t, (length, _, ti, di, plane) in enumerate(lay.terms):
        lin, ang = _segment_columns(length, q[ti], plane if di < 0 else q[di], chain[2 * t][0],
                                    chain[2 * t + 1][1], ptip)
        for r in range(3):
            J[r * n + ti], J[(r + 3) * n + ti] = lin[2 * r], ang[2 * r]
            if di >= 0:
                J[r * n + di], J[(r + 3) * n + di] = lin[2 * r + 1], ang[2 * r + 1]
    return np.array(J).reshape(6, n)


def arm_tip_position(spec: ArmSpec, psi: object) -> Array:
    """Tip position in {w} [m] at ``psi`` (shape (..., n) -> (..., 3))."""
    return arm_frames(spec, psi).tip.copy()

