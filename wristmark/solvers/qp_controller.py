"""Velocity-bounded QP controller formulated in CasADi (kind "qp").

    minimise    w_p || Jv psi_dot - v_ref ||^2 + (Jw psi_dot - w_ref)' W (Jw psi_dot - w_ref)
                + lambda || S (psi_dot - psi_dot_0) ||^2
    subject to  lo <= psi_dot <= hi
                n_k' J_k(psi) psi_dot - dr_k/dpsi psi_dot >= min(-xi (d_k - d_s) / dt, 0)   (k rows, obstacles)

Position only (no orientation task): W = orientation_weight I and w_ref = 0 (the tip frame's
rotation is merely damped; W = 0 for an arm of fewer than 6 joints, which has no joint to spare
for it). With an :class:`OrientationTask` (the pose task): W =
pose_orientation_weight I and w_ref = w_des + sat(kr log(R_des R_meas^T), max_angular_speed)
[rad/s] in {w}; when only the marker's axis z is known (the reference sleeve: roll modulo 30 deg)
W = pose_orientation_weight (I - z z') + orientation_weight z z' and w_ref = (I - z z') (w_des +
sat(kr e_axis)), e_axis the shortest turn of the measured axis onto the desired one: the axis
direction (2 DoF) is controlled and the roll about it only damped, never steered by a guess.
psi_dot_0 = 0, except for an arm of 4 or 5 joints under a position task (nothing holds its null
space): POSTURE_RATE (psi_home - psi) projected onto the null space of Jv (S-weighted), a slow
pull home of the spare joint that stops its drift and leaves the tip alone; with
``feed_forward_undamped`` (position task) psi_dot_0 also holds the least-motion rates that realise
v_des (:meth:`QpController.feed_forward_rates`), so that the damping does not shorten the path's
velocity (it does by 2-5 % on the paper arm, up to 17 % on tendon3: docs/notes/any-arm-residual.md).

v_ref = v_des (feed-forward) + sat(kp (p_des - p_meas), max_correction_speed) + v_i [m/s], v_i the
clamped integral ki sum(e dt) of solvers/tip_integral.py (ki = 0: none; ``integral_mode: path``:
ki G v_des, the mismatch learnt as a map of the desired velocity, which turns with the path at
a corner); Jv, Jw the
linear / angular rows of the 6x6 tip Jacobian in {w}; S = diag(lever, 1, lever, ...) turns
joint rates into tip-scale metres so one damping weight fits rad and m; the box folds in the
velocity limits and psi + psi_dot dt inside the joint limits. The QP is built once as a CasADi
conic (daqp by default) inside one Function with a single packed input
[H (36, column-major), g (6), lo (6), hi (6)], called through a buffer (NOTES.md: ~1 us overhead).

Obstacles (:meth:`QpController.set_obstacles`: other arms' bodies as capsules in this arm's {w}):
the velocity-damper rows of solvers/clearance.py, one per nearby pair of capsules (at most
clearance.MAX_ROWS): d_k [m] the pair's surface distance, d_s = clearance_m [m], n_k the unit
normal from the other body towards this one, J_k the 3 x n Jacobian of this arm's closest axis
point in {w}, r_k its capsule's radius, xi = clearance.DAMPER_GAIN; the other arm is static over
the step. The min(., 0): an arm already inside the clearance may not come closer, and is not
pushed out (psi_dot = 0 meets every row: the QP stays feasible). These rows go to a second
conic built for MAX_ROWS general rows (unused rows: A = 0, lbA = -inf); without obstacles, or
with none near, the box-only conic above runs as before.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm, ArmSpec, home_psi
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import tip_jacobian
from wristmark.models.limits import psi_bounds, velocity_limits
from wristmark.models.so3 import axis_error, rotation_error
from wristmark.solvers.clearance import DAMPER_GAIN, MAX_ROWS, Capsules, clearance_rows
from wristmark.solvers.controller import Controller, ControllerConfig, OrientationTask
from wristmark.solvers.pseudo_inverse import sr_pseudo_inverse
from wristmark.solvers.tip_integral import TipErrorIntegral

Array = NDArray[np.float64]

POSTURE_RATE = 0.5  # [1/s] an arm of 4 or 5 joints under a position task: its null space's pull home
class BoxQp:
    """min 1/2 x'Hx + g'x  s.t. lo <= x <= hi and lbA <= A x (``n`` variables, ``m`` general rows;
    m = 0: the box alone, as fast as before the rows existed), CasADi conic through a buffer.

    The m rows are fixed when the Function is built (once): a solve with fewer rows fills the rest
    with A = 0 and lbA = -inf (no constraint). Packed input [H (n*n, column-major), g, lo, hi,
    A (m*n, column-major), lbA (m)]; the rows' upper bound is +inf."""

    def __init__(self, solver: str = "daqp", n: int = 6, m: int = 0) -> None:
        self.n, self.m = n, m
        nn, mn = n * n, m * n
        x = ca.MX.sym("packed", nn + 3 * n + mn + m)
        H = ca.reshape(x[:nn], n, n)
        opts = {"printLevel": "none"} if solver == "qpoases" else {}
        conic = ca.conic("box_qp", solver, {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity.dense(m, n)
                                            if m else ca.Sparsity(0, n)}, opts)
        args: dict[str, Any] = dict(h=H, g=x[nn:nn + n], lbx=x[nn + n:nn + 2 * n], ubx=x[nn + 2 * n:nn + 3 * n])
        if m:
            o = nn + 3 * n
            args.update(a=ca.reshape(x[o:o + mn], m, n), lba=x[o + mn:o + mn + m], uba=ca.DM.inf(m))
        sol = conic(**args)
        self.function = ca.Function("box_qp_packed", [x], [ca.densify(sol["x"])])
        self._in = np.zeros(nn + 3 * n + mn + m)
        if m:
            self._in[nn + 3 * n + mn:] = -np.inf
        self._out = np.zeros(n)
        self._buf, self._eval = self.function.buffer()
        self._buf.set_arg(0, memoryview(self._in))  # type: ignore[arg-type, call-arg]
        self._buf.set_res(0, memoryview(self._out))  # type: ignore[arg-type, call-arg]

    def solve(self, H: Array, g: Array, lo: Array, hi: Array, A: Array | None = None,
              lbA: Array | None = None) -> Array:
        """Minimiser x (n,); ``A`` (k, n) and ``lbA`` (k,) with k <= m rows lbA <= A x (None: none)."""
        n, nn = self.n, self.n * self.n
        self._in[:nn] = np.asarray(H, float).ravel(order="F")
        self._in[nn:nn + n] = g
        self._in[nn + n:nn + 2 * n] = lo
        self._in[nn + 2 * n:nn + 3 * n] = hi
        if self.m:
            self._set_rows(A, lbA)
        elif A is not None and len(A):
            raise ValueError(f"this QP has no general rows (m = 0), got {len(A)}")
        self._eval()
        return self._out.copy()

    def _set_rows(self, A: Array | None, lbA: Array | None) -> None:
        n, m, o = self.n, self.m, self.n * self.n + 3 * self.n
        k = 0 if A is None else len(A)
        if k > m:
            raise ValueError(f"this QP takes at most {m} general rows, got {k}")
        rows = np.zeros((m, n))
        low = np.full(m, -np.inf)
        if k:
            rows[:k] = A
            low[:k] = np.asarray(lbA, float)
        self._in[o:o + m * n] = rows.ravel(order="F")
        self._in[o + m * n:] = low


def saturate(v: Array, cap: float) -> Array:
    """``v`` scaled down to norm ``cap`` when it is longer."""
    n = float(np.linalg.norm(v))
    return v * (cap / n) if n > cap else v


class QpController(Controller):
    """Feed-forward + saturated proportional feedback, velocity- and joint-bounded (tip in {w} [m],
    tip velocity [m/s], joint velocities [rad/s, m/s]); optionally a pose task (position and
    orientation of the tip frame in {w})."""

    supports_orientation = True
    supports_obstacles = True

    def __init__(self, params: Arm, config: ControllerConfig) -> None:
        super().__init__(params, config)
        self.qp = BoxQp(config.qp_solver, self.n)
        self._row_qp: BoxQp | None = None  # the conic with MAX_ROWS general rows, built at the first obstacles
        self.obstacles: Capsules | None = None
        self.clearance_m = config.clearance_m
        self.clearance_xi = DAMPER_GAIN
        self.influence_m: float | None = None
        lev = config.lever
        # S: rad -> tip metres (lever) for every joint but the prismatic ones (already metres);
        # with n > 6 this damping picks the least-motion solution among the redundant ones
        if isinstance(params, ArmSpec):
            prismatic = set(params.layout.prismatic_list)
            self._S2 = np.diag([1.0 if i in prismatic else lev for i in range(self.n)]) ** 2
        else:
            self._S2 = np.diag([lev, 1.0, lev, lev, lev, lev]) ** 2
        self._vmax = velocity_limits(params)
        # keeping the tip frame's orientation (orientation_weight) needs spare joints: an arm of
        # fewer than 6 has none once the position is served, and the term only makes it lag
        self._keep_orientation = config.orientation_weight if self.n >= 6 else 0.0
        # ... so an arm of 4 or 5 joints under a position task has a null space nothing holds: it
        # drifts along it over a walk (planar: the yaw segment ran to 1 rad and tilted the marker
        # out of view). Its damping pulls psi_dot towards POSTURE_RATE (home - psi) instead of 0.
        self._home = home_psi(params) if 3 < self.n < 6 else None
        self._lo, self._hi = psi_bounds(params)
        self.integral = TipErrorIntegral(config.ki, config.integral_speed_limit)

    def reset(self) -> None:
        """Zero the integral and the backlash state."""
        super().reset()
        self.integral.reset()

    def set_obstacles(self, caps: Capsules | None, clearance_m: float | None = None, xi: float = DAMPER_GAIN,
                      influence_m: float | None = None) -> None:
        """The next :meth:`velocity` calls keep the arm's body at least ``clearance_m`` [m] (None:
        the config's) from the capsules ``caps`` (static, in this arm's {w}; None: no obstacles)
        with the velocity damper of gain ``xi`` in (0, 1] on the pairs within ``influence_m`` [m]
        (None: clearance + clearance.INFLUENCE_MARGIN); see the module docstring."""
        d_s = self.config.clearance_m if clearance_m is None else float(clearance_m)
        if not d_s >= 0.0:
            raise ConfigError(f"'clearance_m' must be >= 0, got {d_s}")
        if not 0.0 < xi <= 1.0:
            raise ConfigError(f"the clearance's damper gain must be in (0, 1], got {xi}")
        if caps is not None and self._row_qp is None:
            self._row_qp = BoxQp(self.config.qp_solver, self.n, MAX_ROWS)
        self.obstacles = caps if caps is not None and len(caps) else None
        self.clearance_m, self.clearance_xi, self.influence_m = d_s, xi, influence_m

    def clearance_rows(self, psi: Array, dt: float) -> tuple[Array, Array]:
        """The obstacles' rows lbA <= A psi_dot at ``psi`` for a step of ``dt`` [s] (none without
        obstacles or with none near): A (k, n), lbA (k,)."""
        if self.obstacles is None:
            return np.zeros((0, self.n)), np.zeros(0)
        return clearance_rows(self.params, psi, self.obstacles, self.clearance_m, dt if dt > 0 else self.config.dt,
                              self.clearance_xi, self.influence_m, MAX_ROWS)

    def _hessian(self, J: Array, W: Array | None = None) -> Array:
        cfg = self.config
        Jv, Jw = J[:3], J[3:]
        W = self._keep_orientation * np.eye(3) if W is None else W
        return 2.0 * (cfg.position_weight * Jv.T @ Jv + Jw.T @ W @ Jw + cfg.damping * self._S2)

    def _posture_rate(self, J: Array, psi: Array) -> Array:
        """POSTURE_RATE (home - psi) [rad/s, m/s] projected onto the null space of the tip's
        linear rows (S-weighted): it moves the spare joint only, never the tip."""
        s_inv = 1.0 / np.sqrt(np.diag(self._S2))
        Js = J[:3] * s_inv  # Jv S^-1
        x0 = POSTURE_RATE * (np.asarray(self._home) - psi)
        y0 = x0 / s_inv  # S x0
        return np.asarray(s_inv * (y0 - np.linalg.pinv(Js) @ (Js @ y0)), float)

    def feed_forward_rates(self, J: Array, v_des: Array) -> Array:
        """The joint rates [rad/s, m/s] that realise the desired tip velocity ``v_des`` [m/s] in {w}
        with the least S-weighted motion (Jv x = v_des; the singularity-robust pseudo-inverse of
        eq. 20 with the config's gamma and xi); the 6 x n Jacobian ``J`` in {w}."""
        cfg = self.config
        s_inv = 1.0 / np.sqrt(np.diag(self._S2))
        A = J[:3] * s_inv  # Jv S^-1
        return np.asarray(s_inv * (sr_pseudo_inverse(A, cfg.gamma, cfg.xi) @ np.asarray(v_des, float)), float)

    def orientation_reference(self, task: OrientationTask) -> tuple[Array, Array]:
        """The orientation task's weight W (3x3) [m^2/rad^2] and reference angular velocity
        w_ref [rad/s] in {w} (see the module docstring)."""
        cfg = self.config
        if not task.axis_only:
            e = rotation_error(task.R_des, task.R_meas)
            return cfg.pose_orientation_weight * np.eye(3), task.w_des + saturate(cfg.kr * e, cfg.max_angular_speed)
        z = np.asarray(task.R_meas, float)[:, 2]
        P = np.eye(3) - np.outer(z, z)
        e = axis_error(np.asarray(task.R_des, float)[:, 2], z)
        W = cfg.pose_orientation_weight * P + cfg.orientation_weight * np.outer(z, z)
        return W, P @ (task.w_des + saturate(cfg.kr * e, cfg.max_angular_speed))

    def path_rates(self, psi: Array, v_tip: Array) -> Array:
        """The QP's unconstrained psi_dot [rad/s, m/s] for a tip velocity ``v_tip`` [m/s] in {w}."""
        J = tip_jacobian(self.params, psi)
        return np.asarray(np.linalg.solve(self._hessian(J), 2.0 * self.config.position_weight * J[:3].T @ v_tip), float)

    def reference_velocity(self, p_meas: Array, p_des: Array, v_des: Array | None,
                           dt: float = 0.0) -> Array:
        """v_ref = v_des + sat(kp (p_des - p_meas)) + v_i [m/s]; ``dt`` [s] advances the integral."""
        cfg = self.config
        err = p_des - p_meas
        saturated = float(np.linalg.norm(cfg.kp * err)) > cfg.max_correction_speed
        fb = saturate(cfg.kp * err, cfg.max_correction_speed)
        if dt > 0.0 and cfg.integral_mode == "path":
            fb = fb + self.integral.update_path(err, v_des, dt, saturated)
        elif dt > 0.0:
            fb = fb + self.integral.update(err, dt, saturated)
        if cfg.feed_forward and v_des is not None:
            fb = fb + v_des
        return fb

    def velocity(self, psi: Array, p_meas: Array, p_des: Array, v_des: Array | None,
                 dt: float, orientation: OrientationTask | None = None) -> tuple[Array, Array, str]:
        """Solve the QP for psi_dot (the pose task when ``orientation`` is given)."""
        v_ref = self.reference_velocity(p_meas, p_des, v_des, dt)
        J = tip_jacobian(self.params, psi)
        if orientation is None:
            H = self._hessian(J)
            g = -2.0 * self.config.position_weight * J[:3].T @ v_ref
            x0 = np.zeros(self.n)
            if self.config.feed_forward_undamped and self.config.feed_forward and v_des is not None:
                x0 = x0 + self.feed_forward_rates(J, v_des)
            if self._home is not None:
                x0 = x0 + self._posture_rate(J, psi)
            if np.any(x0 != 0.0):
                g = g - 2.0 * self.config.damping * self._S2 @ x0
        else:
            W, w_ref = self.orientation_reference(orientation)
            H = self._hessian(J, W)
            g = -2.0 * (self.config.position_weight * J[:3].T @ v_ref + J[3:].T @ W @ w_ref)
        with np.errstate(invalid="ignore"):
            lo = np.maximum(-self._vmax, (self._lo - psi) / dt)
            hi = np.minimum(self._vmax, (self._hi - psi) / dt)
        lo = np.minimum(lo, 0.0)
        hi = np.maximum(hi, 0.0)
        if self.obstacles is None:  # the box alone, as before the obstacles existed
            x = self.qp.solve(H, g, lo, hi)
            if not np.all(np.isfinite(x)):
                return np.zeros(self.n), v_ref, "qp-failed"
            return x, v_ref, "ok"
        return self._solve_with_rows(psi, dt, H, g, lo, hi, v_ref)

    def _solve_with_rows(self, psi: Array, dt: float, H: Array, g: Array, lo: Array, hi: Array,
                         v_ref: Array) -> tuple[Array, Array, str]:
        """The QP with the obstacles' rows (the box-only conic when none is near); status
        "clearance" when a row binds (the step is held back by another arm)."""
        A, lbA = self.clearance_rows(psi, dt)
        if len(A) and self._row_qp is not None:
            x = self._row_qp.solve(H, g, lo, hi, A, lbA)
        else:
            x = self.qp.solve(H, g, lo, hi)
        if not np.all(np.isfinite(x)):
            return np.zeros(self.n), v_ref, "qp-failed"
        if len(A) and bool(np.any(A @ x - lbA < 1e-9 * (1.0 + np.abs(lbA)))):
            return x, v_ref, "clearance"
        return x, v_ref, "ok"
