"""Closed-form kinematics of the whole arm (paper eq. 4): frames and the 6x6 tip Jacobian.

Naming: ``T_a_b`` is the 4x4 pose of frame {b} in frame {a} (it maps b-coordinates to a).
Chain: {w} -> Rz(phi) Tz(d) -> {1b} -> seg 1 -> {1e} -> Tz(L_r) -> {2b} -> seg 2 -> {2e}
-> Tz(l_marker) -> {wm} -> Tz(tip_offset) -> tip. psi = [phi, d, theta1, delta1, theta2, delta2].
This is the one implementation of the chain: the simulated true arm (sim/plant.py) and the
viewer (viz/scene.py) call it too, passing ``stem_bend`` where the exposed stem bends.

Speed: the chain is evaluated on plain Python floats (rotations as row-major 9-tuples) and
copied into numpy once per call; numpy calls on 3x3/4x4 arrays cost more than the arithmetic.
FK + 6x6 Jacobian ~30 us here, against ~540 us with per-matrix numpy (bench/kinematics.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian, check_arm_psi
from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.constant_curvature import Rot, Vec, segment_pose
from wristmark.models.errors import InputError
from wristmark.models.float_chain import _along_z, _compose, _homogeneous_stack, _segment_columns
from wristmark.models.robot_params import RobotParams

Array = NDArray[np.float64]


def check_psi(psi: object, arm: Arm | None = None) -> Array:
    """Return psi as a finite float array of shape (n,) (6 for the reference arm, ``arm.n`` for
    an ArmSpec ``arm``); raise InputError otherwise."""
    if isinstance(arm, ArmSpec):
        q = check_arm_psi(arm, psi)
        if q.ndim != 1:
            raise InputError(f"psi must have {arm.n} entries [{', '.join(arm.names)}], got shape {q.shape}")
        return q
    a = np.asarray(psi, dtype=float)
    if a.shape != (6,):
        raise InputError(
            f"psi must have 6 entries [phi, d, theta1, delta1, theta2, delta2], got shape {a.shape}"
        )
    if not all(map(math.isfinite, a.tolist())):
        raise InputError(f"psi must be finite, got {a.tolist()}")
    return a


@dataclass(frozen=True)
class ArmFrames:
    """Poses in {w} of the arm's frames for one configuration [m]. For an arm of N segments
    (ArmSpec) {1b}, {1e} are the first segment's base and end rings, {2b}, {2e} the last one's,
    and ``segment_bases`` / ``segment_ends`` give every segment's (the reference arm: two)."""

    T_world_1b: Array
    T_world_1e: Array
    T_world_2b: Array
    T_world_2e: Array
    T_world_marker: Array
    T_world_tip: Array
    bases: Array | None = None  # (N, 4, 4) for an ArmSpec; None: [1b, 2b]
    ends: Array | None = None  # (N, 4, 4) for an ArmSpec; None: [1e, 2e]

    @property
    def segment_bases(self) -> list[Array]:
        """Each segment's base ring {tb} in {w}, proximal first."""
        return [self.T_world_1b, self.T_world_2b] if self.bases is None else list(self.bases)

    @property
    def segment_ends(self) -> list[Array]:
        """Each segment's end ring {te} in {w}, proximal first."""
        return [self.T_world_1e, self.T_world_2e] if self.ends is None else list(self.ends)

    @property
    def tip(self) -> Array:
        """Tip position in {w} [m]."""
        return self.T_world_tip[:3, 3]


def _chain(params: RobotParams, q: list[float], stem_bend: float = 0.0) -> list[tuple[Rot, Vec]]:
    """Poses in {w} of {1b}, {1e}, {2b}, {2e}, {wm}, tip as plain floats (see _compose)."""
    phi, d, th1, de1, th2, de2 = q
    L1, L2 = params.segment_lengths
    c, s = math.cos(phi), math.sin(phi)
    R1b: Rot = (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    p1b: Vec = (0.0, 0.0, d)
    if stem_bend != 0.0:  # the exposed stem: an arc of length d bent in segment 1's plane
        R1b, p1b = _compose(R1b, (0.0, 0.0, 0.0), *segment_pose(d, stem_bend, de1))
    R1e, p1e = _compose(R1b, p1b, *segment_pose(L1, th1, de1))
    p2b = _along_z(R1e, p1e, params.rigid_length)
    R2e, p2e = _compose(R1e, p2b, *segment_pose(L2, th2, de2))
    pm = _along_z(R2e, p2e, params.marker_offset)
    ptip = _along_z(R2e, pm, params.tip_offset)
    return [(R1b, p1b), (R1e, p1e), (R1e, p2b), (R2e, p2e), (R2e, pm), (R2e, ptip)]


def forward_kinematics(params: Arm, psi: object, stem_bend: float = 0.0) -> ArmFrames:
    """All frames of the chain in {w} [m] for configuration ``psi`` [rad, m, rad, rad, rad, rad].
    ``stem_bend`` [rad]: the exposed stem (incision to {1b}, length d) bent as a constant-curvature
    arc in segment 1's plane (delta1), as the simulated true arm's stem coupling does; 0 (the model): straight.
    ``params`` may be any arm (ArmSpec, psi of its n entries)."""
    if isinstance(params, ArmSpec):
        return _spec_frames(params, psi, float(stem_bend))
    T = _homogeneous_stack(_chain(params, check_psi(psi).tolist(), float(stem_bend)))
    return ArmFrames(T[0], T[1], T[2], T[3], T[4], T[5])


def _spec_frames(spec: ArmSpec, psi: object, stem_bend: float) -> ArmFrames:
    """forward_kinematics of any arm; a bent stem moves every frame rigidly with {1b}."""
    P = arm_frames(spec, check_psi(psi, spec))
    B, E, M, T = P.T_world_base, P.T_world_end, P.T_world_marker, P.T_world_tip
    if stem_bend != 0.0:
        q = np.asarray(psi, float)
        lay = spec.layout
        phi = float(q[lay.revolute].sum())
        d = float(q[lay.prismatic].sum())
        d1 = spec.segments[0].planar if spec.delta_index[0] is None else float(q[spec.delta_index[0]])
        Rb, pb = _compose((math.cos(phi), -math.sin(phi), 0.0, math.sin(phi), math.cos(phi), 0.0, 0.0, 0.0, 1.0),
                          (0.0, 0.0, 0.0), *segment_pose(d, stem_bend, d1 or 0.0))
        W = _homogeneous_stack([(Rb, pb)])[0] @ np.linalg.inv(B[0])
        B, E, M, T = W @ B, W @ E, W @ M, W @ T
    return ArmFrames(B[0], E[0], B[-1], E[-1], M, T, B, E)


def tip_position(params: Arm, psi: object) -> Array:
    """Tip position in {w} [m]."""
    if isinstance(params, ArmSpec):
        return np.array(arm_frames(params, check_psi(psi, params)).tip)
    return np.array(_chain(params, check_psi(psi).tolist())[5][1])


def _pose_of(T: Array) -> tuple[Rot, Vec]:
    """(R, p) of a 4x4 pose as plain floats."""
    r = T.ravel().tolist()
    return (r[0], r[1], r[2], r[4], r[5], r[6], r[8], r[9], r[10]), (r[3], r[7], r[11])


def tip_jacobian(params: Arm, psi: object, frames: ArmFrames | None = None) -> Array:
    """6x6 Jacobian: rows 0-2 tip linear velocity, rows 3-5 tip-frame angular velocity, in {w}.

    Columns follow psi_dot = [phi_dot, d_dot, theta1_dot, delta1_dot, theta2_dot, delta2_dot].
    ``frames`` (from :func:`forward_kinematics` at the same psi) saves recomputing the chain.
    Any arm (ArmSpec): 6 x n, columns in psi's order.
    """
    if isinstance(params, ArmSpec):
        return arm_tip_jacobian(params, check_psi(psi, params))
    q = check_psi(psi).tolist()
    if frames is None:
        chain = _chain(params, q)
        R1b, R2b = chain[0][0], chain[2][0]
        p1e, p2e, ptip = chain[1][1], chain[3][1], chain[5][1]
    else:
        R1b, R2b = _pose_of(frames.T_world_1b)[0], _pose_of(frames.T_world_2b)[0]
        p1e, p2e = _pose_of(frames.T_world_1e)[1], _pose_of(frames.T_world_2e)[1]
        ptip = _pose_of(frames.T_world_tip)[1]
    L1, L2 = params.segment_lengths
    v1, w1 = _segment_columns(L1, q[2], q[3], R1b, p1e, ptip)
    v2, w2 = _segment_columns(L2, q[4], q[5], R2b, p2e, ptip)
    # fmt: off
    return np.fromiter((
        -ptip[1], 0.0, v1[0], v1[1], v2[0], v2[1],
        ptip[0], 0.0, v1[2], v1[3], v2[2], v2[3],
        0.0, 1.0, v1[4], v1[5], v2[4], v2[5],
        0.0, 0.0, w1[0], w1[1], w2[0], w2[1],
        0.0, 0.0, w1[2], w1[3], w2[2], w2[3],
        1.0, 0.0, w1[4], w1[5], w2[4], w2[5],
    ), np.float64, 36).reshape(6, 6)
    # fmt: on
