"""The arm as a Pinocchio model: pseudo-rigid URDF (models.urdf), the map psi -> q, FK, Jacobian.

psi = [phi, d, theta1, delta1, theta2, delta2] maps to the URDF's joints as
phi -> phi, d -> d and, per segment t with N links: plane_in = -delta_t, bend_0 = bend_N =
theta_t/2N, bend_k = theta_t/N (0 < k < N), chord_k = 2 L_t/theta_t sin(theta_t/2N)
(= L_t/N at theta_t = 0, no division), plane_out = delta_t. The model is exact for every N.
The 6x6 tip Jacobian is J_q(q) dq/dpsi with J_q from ``pin.computeFrameJacobian`` in
LOCAL_WORLD_ALIGNED: rows 0-2 tip linear velocity in {w} [m/s], rows 3-5 tip-frame angular
velocity in {w} [rad/s] (the convention of models.kinematics.tip_jacobian).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from wristmark.models.constant_curvature import f_g
from wristmark.models.errors import InputError, WristmarkError
from wristmark.models.kinematics import ArmFrames, check_psi
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.models.urdf import FRAME_NAMES, generate_urdf

Array = NDArray[np.float64]


class PinocchioArm:
    """Pinocchio model of the arm with ``links_per_segment`` pseudo-rigid links per segment.

    Attributes: ``urdf`` (text), ``model``, ``data``, ``visual_model``, ``collision_model``
    (Pinocchio objects; visual geometry for a Meshcat viewer), ``params``, ``links``.
    """

    def __init__(
        self, params: RobotParams, links_per_segment: int = 8, marker: MarkerModel | None = None
    ) -> None:
        self.params = params
        self.links = links_per_segment
        self.urdf = generate_urdf(params, links_per_segment, marker)
        try:
            self.model = pin.buildModelFromXML(self.urdf)
            self.visual_model = pin.buildGeomFromUrdfString(
                self.model, self.urdf, pin.GeometryType.VISUAL
            )
            self.collision_model = pin.buildGeomFromUrdfString(
                self.model, self.urdf, pin.GeometryType.COLLISION
            )
        except (RuntimeError, ValueError) as e:
            raise WristmarkError(f"Pinocchio could not load the generated URDF: {e}") from e
        self.data = self.model.createData()
        self._frame_ids = {name: self.model.getFrameId(name) for name in FRAME_NAMES}
        self._build_index_maps()

    def _build_index_maps(self) -> None:
        m, n = self.model, self.links
        seg_names = [
            ["plane_in", "bend_0"]
            + [f"{kind}_{k}" for k in range(1, n + 1) for kind in ("chord", "bend")]
            + ["plane_out"]
            for _ in range(2)
        ]
        expected = ["phi", "d"] + [f"seg{t + 1}_{j}" for t in range(2) for j in seg_names[t]]
        actual = [str(m.names[j]) for j in range(1, m.njoints)]
        if actual != expected or m.nq != len(expected) or m.nv != m.nq:
            raise WristmarkError(
                "the generated URDF's joint order is not the chain order "
                "(phi, d, segment joints): regenerate it with models.urdf"
            )
        # q is laid out in chain order, one entry per joint; per segment t it starts at
        # s_t: plane_in, bend_0, chord_1, bend_1, ..., chord_N, bend_N, plane_out.
        self._seg_start = (2, 2 + 2 * n + 3)
        self._A = np.zeros((m.nq, 6))  # the constant (linear) part of dq/dpsi
        self._A[0, 0] = self._A[1, 1] = 1.0
        for t, s in enumerate(self._seg_start):
            th, de = 2 + 2 * t, 3 + 2 * t
            self._A[s, de], self._A[s + 2 * n + 2, de] = -1.0, 1.0
            self._A[s + 1 : s + 2 * n + 2 : 2, th] = 1.0 / n
            self._A[s + 1, th] = self._A[s + 2 * n + 1, th] = 0.5 / n

    def _chords(self, theta: float, length: float) -> tuple[float, float]:
        """Chord length [m] and its derivative w.r.t. theta [m/rad] for one link."""
        n = self.links
        _, g, _, dg = f_g(theta / (2.0 * n))  # g(x) = sin(x)/x, smooth at 0
        return length / n * g, length / n * dg / (2.0 * n)

    def q_from_psi(self, psi: object) -> Array:
        """Pinocchio configuration q (nq,) [rad, m] for psi."""
        v = check_psi(psi).tolist()
        n = self.links
        out = [v[0], v[1]]
        for t in range(2):
            th, de = v[2 + 2 * t], v[3 + 2 * t]
            c, _ = self._chords(th, self.params.segment_lengths[t])
            b = th / n
            out += (-de, 0.5 * b)
            out += (c, b) * (n - 1)
            out += (c, 0.5 * b, de)
        return np.array(out)

    def dq_dpsi(self, psi: object) -> Array:
        """Jacobian dq/dpsi, shape (nq, 6), analytic."""
        v = check_psi(psi).tolist()
        n = self.links
        D = self._A.copy()
        for t, s in enumerate(self._seg_start):
            _, dc = self._chords(v[2 + 2 * t], self.params.segment_lengths[t])
            D[s + 2 : s + 2 * n + 1 : 2, 2 + 2 * t] = dc
        return D

    def frame_id(self, name: str) -> int:
        """Pinocchio frame index of ``name`` (one of FRAME_NAMES or any URDF link/joint)."""
        fid = self._frame_ids.get(name)
        if fid is None:
            if not self.model.existFrame(name):
                raise InputError(f"unknown frame '{name}' (known: {', '.join(FRAME_NAMES)})")
            fid = self.model.getFrameId(name)
        return int(fid)

    def frame_pose(self, name: str, psi: object) -> Array:
        """4x4 pose of frame ``name`` in {w} at psi [m]."""
        fid = self.frame_id(name)
        q = self.q_from_psi(psi)
        pin.framesForwardKinematics(self.model, self.data, q)
        return np.array(self.data.oMf[fid].homogeneous)

    def forward(self, psi: object) -> ArmFrames:
        """All named frames in {w} at psi (same dataclass as the closed form)."""
        q = self.q_from_psi(psi)
        pin.framesForwardKinematics(self.model, self.data, q)
        oMf, ids = self.data.oMf, self._frame_ids
        T = [oMf[ids[n]].homogeneous for n in FRAME_NAMES]  # fresh numpy arrays
        return ArmFrames(*T)

    def tip_jacobian(self, psi: object) -> Array:
        """6x6 tip Jacobian J_q(q) dq/dpsi: linear (rows 0-2) and angular (3-5) in {w}."""
        p = check_psi(psi)
        q = self.q_from_psi(p)
        Jq = pin.computeFrameJacobian(
            self.model, self.data, q, self._frame_ids["tip"], pin.LOCAL_WORLD_ALIGNED
        )
        return np.asarray(Jq @ self.dq_dpsi(p))
