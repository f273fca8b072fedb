"""Any arm as a Pinocchio model: models.arm_urdf's pseudo-rigid URDF, the map psi -> q, frames
and the 6 x n tip Jacobian (an independent check of models.arm_kinematics).

psi maps to the URDF's joints as: each stem joint -> itself; per segment t with N links:
plane_in = -delta_t, bend_0 = bend_N = theta_t/2N, bend_k = theta_t/N (0 < k < N),
chord_k = (L_t/N) g(theta_t/2N) with g(x) = sin(x)/x (no division at 0), plane_out = delta_t
(a planar segment has no plane joints: they are fixed at its plane). The tip Jacobian is
J_q(q) dq/dpsi with J_q in LOCAL_WORLD_ALIGNED: rows 0-2 linear [m/s], 3-5 angular [rad/s], in {w}.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from wristmark.models.arm_kinematics import ArmPoses, check_arm_psi
from wristmark.models.arm_spec import ArmSpec
from wristmark.models.arm_urdf import arm_frame_names, generate_arm_urdf, segment_joint_names
from wristmark.models.constant_curvature import f_g
from wristmark.models.errors import InputError, WristmarkError
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]


class PinocchioAnyArm:
    """Pinocchio model of ``spec`` with ``links_per_segment`` pseudo-rigid links per segment.

    Attributes: ``urdf`` (text), ``model``, ``data``, ``visual_model``, ``spec``, ``links``.
    """

    def __init__(self, spec: ArmSpec, links_per_segment: int = 8, marker: MarkerModel | None = None) -> None:
        self.spec = spec
        self.links = links_per_segment
        self.urdf = generate_arm_urdf(spec, links_per_segment, marker)
        try:
            self.model = pin.buildModelFromXML(self.urdf)
            self.visual_model = pin.buildGeomFromUrdfString(self.model, self.urdf, pin.GeometryType.VISUAL)
        except (RuntimeError, ValueError) as e:
            raise WristmarkError(f"Pinocchio could not load the generated URDF: {e}") from e
        self.data = self.model.createData()
        self.frame_names = arm_frame_names(spec)
        self._frame_ids = {n: int(self.model.getFrameId(n, pin.FrameType.BODY)) for n in self.frame_names}
        self._build_index_maps()

    def _build_index_maps(self) -> None:
        m, n, spec = self.model, self.links, self.spec
        expected = [j.name for j in spec.stem]
        self._seg_start: list[int] = []
        for t, seg in enumerate(spec.segments, 1):
            self._seg_start.append(len(expected))
            expected += segment_joint_names(seg, t, n)
        actual = [str(m.names[j]) for j in range(1, m.njoints)]
        if actual != expected or m.nq != len(expected) or m.nv != m.nq:
            raise WristmarkError("the generated URDF's joint order is not the chain order: regenerate it")
        self._A = np.zeros((m.nq, spec.n))  # the constant part of dq/dpsi
        for i in range(len(spec.stem)):
            self._A[i, i] = 1.0
        for s, ti, di in zip(self._seg_start, spec.theta_index, spec.delta_index):
            bends = s + (0 if di is None else 1)  # bend_0 at bends, bend_k at bends + 2k
            self._A[bends : bends + 2 * n + 1 : 2, ti] = 1.0 / n
            self._A[bends, ti] = self._A[bends + 2 * n, ti] = 0.5 / n
            if di is not None:
                self._A[s, di], self._A[bends + 2 * n + 1, di] = -1.0, 1.0

    def _chord(self, theta: float, length: float) -> tuple[float, float]:
        """Chord length [m] of one link and its derivative w.r.t. theta [m/rad]."""
        n = self.links
        _, g, _, dg = f_g(theta / (2.0 * n))
        return length / n * g, length / n * dg / (2.0 * n)

    def q_from_psi(self, psi: object) -> Array:
        """Pinocchio configuration q (nq,) [rad, m] for psi (n,)."""
        v = check_arm_psi(self.spec, psi).tolist()
        n = self.links
        out = v[: len(self.spec.stem)]
        for seg, ti, di in zip(self.spec.segments, self.spec.theta_index, self.spec.delta_index):
            th = v[ti]
            c, _ = self._chord(th, seg.length)
            b = th / n
            inner = [0.5 * b] + [c, b] * (n - 1) + [c, 0.5 * b]
            out += inner if di is None else [-v[di], *inner, v[di]]
        return np.array(out)

    def dq_dpsi(self, psi: object) -> Array:
        """Jacobian dq/dpsi, shape (nq, n), analytic."""
        v = check_arm_psi(self.spec, psi).tolist()
        n = self.links
        D = self._A.copy()
        for s, seg, ti, di in zip(self._seg_start, self.spec.segments, self.spec.theta_index, self.spec.delta_index):
            chords = s + (0 if di is None else 1) + 1  # chord_1; chord_k at chords + 2(k-1)
            D[chords : chords + 2 * n - 1 : 2, ti] = self._chord(v[ti], seg.length)[1]
        return D

    def frame_pose(self, name: str, psi: object) -> Array:
        """4x4 pose of frame ``name`` (one of ``frame_names`` or any URDF link) in {w} at psi [m]."""
        fid = self._frame_ids.get(name)
        if fid is None:
            if not self.model.existFrame(name):
                raise InputError(f"unknown frame '{name}' (known: {', '.join(self.frame_names)})")
            fid = int(self.model.getFrameId(name))
        pin.framesForwardKinematics(self.model, self.data, self.q_from_psi(psi))
        return np.array(self.data.oMf[fid].homogeneous)

    def forward(self, psi: object) -> ArmPoses:
        """All named frames in {w} at psi (the dataclass of models.arm_kinematics)."""
        pin.framesForwardKinematics(self.model, self.data, self.q_from_psi(psi))
        T = np.array([self.data.oMf[self._frame_ids[n]].homogeneous for n in self.frame_names])
        return ArmPoses(T[0:-2:2], T[1:-2:2], T[-2], T[-1])

    def tip_jacobian(self, psi: object) -> Array:
        """6 x n tip Jacobian J_q(q) dq/dpsi: linear (rows 0-2) and angular (3-5) in {w}."""
        q = self.q_from_psi(psi)
        Jq = pin.computeFrameJacobian(self.model, self.data, q, self._frame_ids["tip"], pin.LOCAL_WORLD_ALIGNED)
        return np.asarray(Jq @ self.dq_dpsi(psi))
