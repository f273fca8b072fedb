"""Stereo reprojection pose solve of the wrist marker (paper eq. 16) in CasADi.

Unknown: the pose of {wm} in the left camera frame {ll}. Both cameras' intrinsics and distortion
[k1, k2, p1, p2, k3] (OpenCV model) and the stereo extrinsics X_right = R X_left + T enter the
projection. The solve is a fixed number of Levenberg-Marquardt steps (local increment on SO(3):
R <- R exp([w]x), translation in millimetres for conditioning; a step is kept only if it lowers
the cost) unrolled into ONE ``ca.Function`` with ONE packed input vector, called through
``F.buffer()`` with memoryviews (NOTES.md). Variable numbers of visible corners are handled by a
per-slot weight (0 = absent) in the packed input; each camera has ``max_points`` slots.

Packed input: R0 (9, row-major), t0 (3) [m], left fx fy cx cy skew (5), left dist (5), right
intrinsics (5), right dist (5), R (9, row-major), T (3) [m], then ``max_points`` left slots and
``max_points`` right slots of [X, Y, Z (marker frame, m), u, v (raw px), weight].
Packed output: R (9), t (3), then per slot the weighted residual (u, v) [px], left then right.

Symmetries (documented, not bugs): corner indices are relative, so roll about z_wm is only
known modulo the pattern period beta = 2 pi / columns; and the checkered sleeve is invariant
under a half turn about x_wm (i -> -i, z -> -z), so the direction of z_wm is fixed by a prior
(``PoseSettings.axis_hint_left``: the expected direction of z_wm in {ll}); cvs.tracking.tracker
decides it from the previous pair, a caller's hint or the image (cvs.tracking.axis) first.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, replace
from pathlib import Path

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.cvs.tracking.compiled_function import load
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]
_HEAD = 9 + 3 + 10 + 10 + 12  # pose start, two cameras, stereo extrinsics
_SLOT = 6  # X, Y, Z, u, v, weight
_MM = 1e-3  # translation increments are solved in millimetres [m/mm]
_SOURCE = Path(__file__).read_bytes()  # what the pose function is built from
HALF_TURN_X = np.diag([1.0, -1.0, -1.0, 1.0])  # the sleeve's symmetry: a half turn about x_wm


@dataclass(frozen=True)
class PoseSettings:
    """Solver and outlier-rejection settings.

    steps: unrolled LM steps; lm_lambda: initial Marquardt damping (relative to diag(J'J));
    outlier_factor: a point is an outlier if its residual exceeds outlier_factor * median
    residual and outlier_floor_px [px]; single_view_factor: the same test with this factor
    instead, stricter, for a corner that the other camera does not see (nothing checks it
    against its partner: a one-view corner under a highlight stripe 1.7 px off, spread by the
    fit to 1.05 px against 0.2-0.5 px elsewhere, pulled a path-traced pose 0.43 mm off), where
    the fit has at least single_view_min_pairs corners seen by both cameras
    (single_view_factor 0: off); max_rounds: re-solves after rejections;
    axis_hint_left: expected direction of z_wm (distal) in {ll}, or None to keep the solution
    as solved. Default (1, 0, 0): the arm enters from the left of the image (configs/camera.yaml).
    """

    steps: int = 12
    lm_lambda: float = 1e-4
    outlier_factor: float = 4.0
    outlier_floor_px: float = 0.75
    single_view_factor: float = 2.0
    single_view_min_pairs: int = 3
    max_rounds: int = 2
    axis_hint_left: tuple[float, float, float] | None = (1.0, 0.0, 0.0)

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        if not 1 <= self.steps <= 100:
            raise ConfigError(f"'steps' must be in 1..100, got {self.steps}")
        if not self.lm_lambda >= 0:
            raise ConfigError(f"'lm_lambda' must be >= 0, got {self.lm_lambda}")
        if not (self.outlier_factor > 1 and self.outlier_floor_px > 0):
            raise ConfigError("'outlier_factor' must be > 1 and 'outlier_floor_px' > 0")
        if not (self.single_view_factor == 0 or self.single_view_factor > 1):
            raise ConfigError(f"'single_view_factor' must be 0 (off) or > 1, got {self.single_view_factor}")
        if self.single_view_min_pairs < 1:
            raise ConfigError(f"'single_view_min_pairs' must be >= 1, got {self.single_view_min_pairs}")
        if self.max_rounds < 0:
            raise ConfigError(f"'max_rounds' must be >= 0, got {self.max_rounds}")


@dataclass(frozen=True)
class MarkerPose:
    """Result of the stereo pose solve (left camera frame {ll}, metres).

    T_fit: 4x4 pose of {wm} in {ll} as fitted, consistent with the corner indices given (the
    start for the next pair); T_left_marker: the reported pose, T_fit or T_fit turned half about
    x_wm to point z_wm as the prior says (the fit then holds with corner i as -i); tip_left: tip
    (eq. 5) of the reported pose in {ll} [m]; tip_world: tip
    in {w} [m] when the calibration has world_T_left, else None; rms_px: RMS reprojection
    residual of the inliers [px]; n_left, n_right: corners given per camera; inliers_left/right:
    boolean masks of the corners kept; roll_ambiguity_rad = beta: roll about z_wm is only known
    modulo the pattern period beta = 2 pi / columns (corner indices are relative); time_ms: wall
    time of the solve [ms].
    """

    T_fit: Array
    T_left_marker: Array
    tip_left: Array
    tip_world: Array | None
    rms_px: float
    n_left: int
    n_right: int
    inliers_left: NDArray[np.bool_]
    inliers_right: NDArray[np.bool_]
    roll_ambiguity_rad: float
    time_ms: float

    @property
    def inliers(self) -> int:
        """Number of corners (both cameras) kept after outlier rejection."""
        return int(self.inliers_left.sum() + self.inliers_right.sum())


def _skew(w: ca.SX) -> ca.SX:
    return ca.vertcat(
        ca.horzcat(0, -w[2], w[1]),
        ca.horzcat(w[2], 0, -w[0]),
        ca.horzcat(-w[1], w[0], 0),
    )


def _expm(w: ca.SX) -> ca.SX:
    """Rodrigues' formula, finite at w = 0 (the tiny offset only guards 0/0)."""
    th2 = ca.dot(w, w)
    th = ca.sqrt(th2 + 1e-30)
    S = _skew(w)
    return ca.SX.eye(3) + (ca.sin(th) / th) * S + ((1 - ca.cos(th)) / (th * th)) * (S @ S)


def _project(P: ca.SX, intr: ca.SX, dist: ca.SX) -> tuple[ca.SX, ca.SX]:
    """OpenCV pinhole + distortion projection of camera-frame points (3 x n) to pixels."""
    x = P[0, :] / P[2, :]
    y = P[1, :] / P[2, :]
    r2 = x * x + y * y
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    fx, fy, cx, cy, s = intr[0], intr[1], intr[2], intr[3], intr[4]
    return fx * xd + s * yd + cx, fy * yd + cy


def build_pose_function(max_points: int, steps: int = 12, lm_lambda: float = 1e-4) -> ca.Function:
    """The unrolled LM solve as one CasADi Function ``packed input -> packed output`` (module doc)."""
    M = max_points
    n_in = _HEAD + 2 * M * _SLOT
    x = ca.SX.sym("packed", n_in)
    intr_l, dist_l = x[12:17], x[17:22]
    intr_r, dist_r = x[22:27], x[27:32]
    R_rl = ca.reshape(x[32:41], 3, 3).T
    T_rl = x[41:44]
    slots_l = ca.reshape(x[_HEAD : _HEAD + M * _SLOT], _SLOT, M)
    slots_r = ca.reshape(x[_HEAD + M * _SLOT :], _SLOT, M)

    def residual(R: ca.SX, t: ca.SX) -> ca.SX:
        out = []
        for slots, intr, dist, right in ((slots_l, intr_l, dist_l, False), (slots_r, intr_r, dist_r, True)):
            Pc = R @ slots[0:3, :] + ca.repmat(t, 1, M)
            if right:
                Pc = R_rl @ Pc + ca.repmat(T_rl, 1, M)
            u, v = _project(Pc, intr, dist)
            sw = ca.sqrt(slots[5, :])
            out += [sw * (u - slots[3, :]), sw * (v - slots[4, :])]
        # order: left u (M), left v (M), right u, right v
        return ca.vertcat(*[ca.reshape(o, M, 1) for o in out])

    Rs = ca.SX.sym("R", 3, 3)
    ts = ca.SX.sym("t", 3)
    d = ca.SX.sym("d", 6)
    r_lin = residual(Rs @ (ca.SX.eye(3) + _skew(d[:3])), ts + _MM * d[3:])
    J = ca.substitute(ca.jacobian(r_lin, d), d, ca.DM.zeros(6))
    r0 = ca.substitute(r_lin, d, ca.DM.zeros(6))
    lin = ca.Function("lin", [Rs, ts, x], [r0, J])
    cost_f = ca.Function("cost", [Rs, ts, x], [ca.sumsqr(r0)])

    R = ca.reshape(x[0:9], 3, 3).T
    t = x[9:12]
    lam = ca.SX(lm_lambda)
    for _ in range(steps):
        r, Jk = lin(R, t, x)
        H = Jk.T @ Jk
        g = Jk.T @ r
        Hd = H + lam * ca.diag(ca.diag(H)) + 1e-12 * ca.SX.eye(6)
        step = -ca.solve(Hd, g)
        R_new = R @ _expm(step[:3])
        t_new = t + _MM * step[3:]
        c_old = ca.sumsqr(r)
        c_new = cost_f(R_new, t_new, x)
        better = c_new < c_old
        R = ca.if_else(better, R_new, R)
        t = ca.if_else(better, t_new, t)
        lam = ca.if_else(better, lam * 0.1, lam * 10.0)
    r_fin, _ = lin(R, t, x)
    out = ca.vertcat(ca.reshape(R.T, 9, 1), t, r_fin)
    return ca.Function("stereo_pose_lm", [x], [ca.densify(out)])


def pose_function_key(max_points: int, steps: int, lm_lambda: float) -> str:
    """A digest of what :func:`build_pose_function` builds from: its arguments and this module's
    source (the compiled solve's cache key, cvs.tracking.compiled_function)."""
    return hashlib.sha256(f"{max_points}|{steps}|{lm_lambda!r}|".encode() + _SOURCE).hexdigest()[:16]


def _camera_head(cam: Camera) -> list[float]:
    K = np.asarray(cam.K, float)
    return [K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1], *np.asarray(cam.dist, float).tolist()]


class StereoPoseSolver:
    """Pose of {wm} in {ll} from indexed corners in both images (paper eq. 16), CasADi LM.

    Built once per calibration and marker (~0.1-0.5 s); each ``solve`` costs well under 1 ms.
    """

    def __init__(self, camera: StereoCamera, marker: MarkerModel, settings: PoseSettings | None = None) -> None:
        self.settings = settings or PoseSettings()
        self.settings.validate()
        camera.validate()
        marker.validate()
        self.camera = camera
        self.marker = marker
        self.max_points = marker.columns
        self.function = build_pose_function(self.max_points, self.settings.steps, self.settings.lm_lambda)
        self._in = np.zeros(_HEAD + 2 * self.max_points * _SLOT)
        self._out = np.zeros(12 + 4 * self.max_points)
        self._in[12:32] = _camera_head(camera.left) + _camera_head(camera.right)
        self._in[32:41] = np.asarray(camera.R, float).reshape(9)
        self._in[41:44] = np.asarray(camera.T, float)
        self._buf, self._eval = self.function.buffer()
        self._buf.set_arg(0, memoryview(self._in))  # type: ignore[arg-type, call-arg]
        self._buf.set_res(0, memoryview(self._out))  # type: ignore[arg-type, call-arg]
        # the same solve compiled (cvs.tracking.compiled_function: bit for bit the same outputs,
        # faster, and without the interpreter lock) when it was built; else CasADi evaluates
        key = pose_function_key(self.max_points, self.settings.steps, self.settings.lm_lambda)
        self.compiled = load(self.function, key, self._in, self._out)
        if self.compiled is not None:
            self._eval = self.compiled
        self._corners = marker.corners()

    def marker_points(self, index: NDArray[np.int_]) -> Array:
        """Corner positions in {wm} [m] for relative corner indices (taken modulo columns)."""
        return self._corners[np.mod(np.asarray(index, int), self.marker.columns)]

    def _run(
        self, T0: Array, P_l: Array, uv_l: Array, w_l: Array, P_r: Array, uv_r: Array, w_r: Array
    ) -> tuple[Array, Array, Array]:
        """One packed evaluation; returns T, residual norms left (n_l,), right (n_r,) [px]."""
        M = self.max_points
        self._in[0:9] = T0[:3, :3].reshape(9)
        self._in[9:12] = T0[:3, 3]
        for k, (P, uv, w) in enumerate(((P_l, uv_l, w_l), (P_r, uv_r, w_r))):
            s = self._in[_HEAD + k * M * _SLOT : _HEAD + (k + 1) * M * _SLOT].reshape(M, _SLOT)
            s[:] = 0.0
            s[:, 2] = 1.0  # harmless dummy points for empty slots (weight 0)
            n = P.shape[0]
            s[:n, 0:3], s[:n, 3:5], s[:n, 5] = P, uv, w
        self._eval()
        T = np.eye(4)
        T[:3, :3] = self._out[0:9].reshape(3, 3)
        T[:3, 3] = self._out[9:12]
        r = self._out[12:].reshape(4, M)
        norm_l = np.hypot(r[0], r[1])[: P_l.shape[0]]
        norm_r = np.hypot(r[2], r[3])[: P_r.shape[0]]
        return T, norm_l, norm_r

    def solve(
        self,
        index_left: NDArray[np.int_],
        uv_left: Array,
        index_right: NDArray[np.int_],
        uv_right: Array,
        T_left_marker_init: Array,
        sigmas: tuple[Array, Array] | None = None,
    ) -> MarkerPose:
        """Refine the pose from relative corner indices and raw pixels of each camera.

        index_*: (n,) relative marker corner indices (consistent between the cameras, unique per
        camera, n <= columns); uv_*: (n, 2) raw pixels; T_left_marker_init: 4x4 start (e.g. the
        homography pose); sigmas: optional per-corner noise (left (n_l,), right (n_r,)) [px],
        each corner weighted by (least sigma / its sigma)^2 (the outlier test and rms_px stay in
        unweighted pixels). Raises InputError on malformed input or fewer than 4 corners in all.
        """
        t_start = time.perf_counter()
        il, ir = np.asarray(index_left, int).reshape(-1), np.asarray(index_right, int).reshape(-1)
        ul, ur = np.asarray(uv_left, float).reshape(-1, 2), np.asarray(uv_right, float).reshape(-1, 2)
        if il.size != ul.shape[0] or ir.size != ur.shape[0]:
            raise InputError("each corner needs one index: index and uv arrays differ in length")
        for name, idx in (("left", il), ("right", ir)):
            if idx.size > self.max_points or np.unique(np.mod(idx, self.marker.columns)).size != idx.size:
                raise InputError(f"{name} corner indices must be unique modulo {self.marker.columns}")
        if il.size + ir.size < 4:
            raise InputError(f"the pose needs >= 4 corners in all, got {il.size + ir.size}")
        if not (np.all(np.isfinite(ul)) and np.all(np.isfinite(ur))):
            raise InputError("corner pixels must be finite (got NaN or inf)")
        T0 = np.asarray(T_left_marker_init, float)
        if T0.shape != (4, 4) or not np.all(np.isfinite(T0)):
            raise InputError("T_left_marker_init must be a finite 4x4 transform")
        P_l, P_r = self.marker_points(il), self.marker_points(ir)
        w_l, w_r = np.ones(il.size), np.ones(ir.size)
        scale_l, scale_r = np.ones(il.size), np.ones(ir.size)  # weighted -> pixel residuals
        if sigmas is not None:
            sg_l, sg_r = (np.asarray(v, float).reshape(-1) for v in sigmas)
            if sg_l.size != il.size or sg_r.size != ir.size or not np.all(np.concatenate([sg_l, sg_r]) > 0):
                raise InputError("sigmas need one positive value per corner of each camera")
            least = float(np.concatenate([sg_l, sg_r]).min())
            scale_l, scale_r = sg_l / least, sg_r / least
            w_l, w_r = scale_l**-2, scale_r**-2
        T, e_l, e_r = self._run(T0, P_l, ul, w_l, P_r, ur, w_r)
        e_l, e_r = e_l * scale_l, e_r * scale_r
        s = self.settings
        cols = self.marker.columns
        one_l = ~np.isin(np.mod(il, cols), np.mod(ir, cols))  # corners the other camera does not see
        one_r = ~np.isin(np.mod(ir, cols), np.mod(il, cols))
        strict = s.single_view_factor > 0 and int((~one_l).sum()) >= s.single_view_min_pairs
        for _ in range(s.max_rounds):
            e = np.concatenate([e_l[w_l > 0], e_r[w_r > 0]])
            med = float(np.median(e))
            lim = max(s.outlier_factor * med, s.outlier_floor_px)
            bad_l, bad_r = (w_l > 0) & (e_l > lim), (w_r > 0) & (e_r > lim)
            if strict:
                lim_one = max(s.single_view_factor * med, s.outlier_floor_px)
                bad_l |= (w_l > 0) & one_l & (e_l > lim_one)
                bad_r |= (w_r > 0) & one_r & (e_r > lim_one)
            if not (bad_l.any() or bad_r.any()) or (w_l.sum() + w_r.sum() - bad_l.sum() - bad_r.sum()) < 4:
                break
            w_l[bad_l], w_r[bad_r] = 0.0, 0.0
            T, e_l, e_r = self._run(T, P_l, ul, w_l, P_r, ur, w_r)
            e_l, e_r = e_l * scale_l, e_r * scale_r
        e = np.concatenate([e_l[w_l > 0], e_r[w_r > 0]])
        rms = float(np.sqrt(np.mean(e**2))) if e.size else float("nan")
        return self._result(T, rms, w_l > 0, w_r > 0, t_start)

    def orient(self, T_left_marker: Array) -> Array:
        """Apply the z_wm prior ``settings.axis_hint_left``: a half turn about x_wm if z_wm points
        against it (the fit then holds with corner i as -i; None: unchanged)."""
        hint = self.settings.axis_hint_left
        if hint is not None and float(np.dot(T_left_marker[:3, 2], np.asarray(hint, float))) < 0:
            return T_left_marker @ HALF_TURN_X
        return T_left_marker

    def half_turned(self, pose: MarkerPose) -> MarkerPose:
        """The same fit reported with the other direction of z_wm (the sleeve's half-turn
        symmetry, under which corner i takes the place of corner -i; ``T_fit`` is unchanged)."""
        T = pose.T_left_marker @ HALF_TURN_X
        tip_left, tip_world = self._tips(T)
        return replace(pose, T_left_marker=T, tip_left=tip_left, tip_world=tip_world)

    def _tips(self, T: Array) -> tuple[Array, Array | None]:
        """Tip (eq. 5) in {ll} and, with world_T_left, in {w} [m] for the pose T of {wm} in {ll}."""
        tip_left = T[:3, :3] @ self.marker.tip() + T[:3, 3]
        tip_world = None if self.camera.T_world_left is None else self.camera.world_from_left(tip_left)[0]
        return tip_left, tip_world

    def _result(
        self, T_fit: Array, rms: float, in_l: NDArray[np.bool_], in_r: NDArray[np.bool_], t_start: float
    ) -> MarkerPose:
        T = self.orient(T_fit)
        tip_left, tip_world = self._tips(T)
        return MarkerPose(
            T_fit=T_fit,
            T_left_marker=T,
            tip_left=tip_left,
            tip_world=tip_world,
            rms_px=rms,
            n_left=int(in_l.size),
            n_right=int(in_r.size),
            inliers_left=in_l,
            inliers_right=in_r,
            roll_ambiguity_rad=self.marker.beta,
            time_ms=1e3 * (time.perf_counter() - t_start),
        )
