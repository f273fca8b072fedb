"""The paper's resolved-rate controller (Sec. III.C, eq. 17-21).

dp = p_d - p_c (17); v = v_xlim dp / |dp| (18); psi_dot = J^+ [v; w] with w = 0 (19), J the
full 6x6 Jacobian at the commanded configuration; J^+ = J^T (J J^T + gamma I)^-1 when the
smallest singular value sigma_min < xi, else the Moore-Penrose pseudo-inverse (20);
psi <- psi + psi_dot dt (21, in Controller.step). With saturate_near_target the speed is
min(v_xlim, |dp| / dt), which removes the +-v_xlim dt chatter of the constant-speed law.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from models.kinematics import tip_jacobian
from solvers.controller import Controller

Array = NDArray[np.float64]


def sr_pseudo_inverse(J: Array, gamma: float, xi: float) -> Array:
    """Eq. 20: damped pseudo-inverse when the smallest singular value is below xi."""
    s = np.linalg.svd(J, compute_uv=False)
    if s[-1] < xi:
        return np.asarray(J.T @ np.linalg.inv(J @ J.T + gamma * np.eye(J.shape[0])), float)
    return np.asarray(np.linalg.pinv(J), float)


class PaperController(Controller):
    """Constant-speed resolved-rate control, exactly the paper's eq. 17-21."""

    def velocity(self, psi: Array, p_meas: Array, p_des: Array, v_des: Array | None,
                 dt: float) -> tuple[Array, Array, str]:
        """psi_dot from eq. 17-20 (v_des unused: the paper has no feed-forward)."""
        cfg = self.config
        dp = p_des - p_meas
        n = float(np.linalg.norm(dp))
        if n == 0.0:
            return np.zeros(6), np.zeros(3), "at-target"
        speed = min(cfg.v_xlim, n / dt) if cfg.saturate_near_target else cfg.v_xlim
        v = speed * dp / n
        J = tip_jacobian(self.params, psi)
        Jp = sr_pseudo_inverse(J, cfg.gamma, cfg.xi)
        return Jp @ np.concatenate([v, np.zeros(3)]), v, "ok"
