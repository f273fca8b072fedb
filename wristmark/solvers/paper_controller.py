"""The paper's resolved-rate controller (Sec. III.C, eq. 17-21).

dp = p_d - p_c (17); v = v_xlim dp / |dp| (18); psi_dot = J^+ [v; w] with w = 0 (19), J the
full 6x6 Jacobian at the commanded configuration; J^+ = J^T (J J^T + gamma I)^-1 when the
smallest singular value sigma_min < xi, else the Moore-Penrose pseudo-inverse (20);
psi <- psi + psi_dot dt (21, in Controller.step). With saturate_near_target the speed is
min(v_xlim, |dp| / dt), which removes the +-v_xlim dt chatter of the constant-speed law.

Joint limits (not in the paper; ``lock_saturated_joints``, default on): a joint that the step
would drive through its limit is locked (its Jacobian column zeroed) and eq. 19-20 solved again
for the others, so the remaining joints make up the motion it cannot give; off, the step is
clipped to the limits afterwards and that part of the motion is lost (at the stem feed's
lower end stop this left the tip 3-4 mm behind on the cube).

Position only, as the paper defines it (w = 0 in eq. 19 is a zero angular *velocity*, not an
orientation task): asked for an orientation, ``Controller.step`` refuses with a ConfigError,
and the command line refuses ``--orientation hold|follow`` with ``--controller paper``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.models.kinematics import tip_jacobian
from wristmark.models.limits import psi_bounds
from wristmark.solvers.controller import Controller, OrientationTask
from wristmark.solvers.pseudo_inverse import sr_pseudo_inverse

Array = NDArray[np.float64]


class PaperController(Controller):
    """Constant-speed resolved-rate control, exactly the paper's eq. 17-21 (tip in {w} [m], speed
    ``v_xlim`` [m/s])."""

    def velocity(self, psi: Array, p_meas: Array, p_des: Array, v_des: Array | None,
                 dt: float, orientation: OrientationTask | None = None) -> tuple[Array, Array, str]:
        """psi_dot from eq. 17-20 (v_des unused: the paper has no feed-forward)."""
        cfg = self.config
        dp = p_des - p_meas
        n = float(np.linalg.norm(dp))
        if n == 0.0:
            return np.zeros(psi.size), np.zeros(3), "at-target"
        speed = min(cfg.v_xlim, n / dt) if cfg.saturate_near_target else cfg.v_xlim
        v = speed * dp / n
        J = tip_jacobian(self.params, psi)
        twist = np.concatenate([v, np.zeros(3)])
        if self.n < 6:  # fewer joints than a pose (eq. 19 asks for a zero angular rate): position rows only
            J, twist = J[:3], v
        psi_dot = sr_pseudo_inverse(J, cfg.gamma, cfg.xi) @ twist
        if not cfg.lock_saturated_joints:
            return psi_dot, v, "ok"
        lo, hi = psi_bounds(self.params)
        free = np.ones(psi.size, bool)
        for _ in range(psi.size):  # lock the joints the step would push through a limit, solve again
            nxt = psi + psi_dot * dt
            out = free & (((nxt < lo) & (psi_dot < 0)) | ((nxt > hi) & (psi_dot > 0)))
            if not out.any():
                break
            free &= ~out
            psi_dot = sr_pseudo_inverse(J * free, cfg.gamma, cfg.xi) @ twist
        return psi_dot, v, "ok" if free.all() else "joint-locked"
