"""Camera-to-robot registration: world_T_left (pose of {ll} in {w}) from tracked marker poses.

Each observation is the marker centre c_l and z axis a_l in {ll} (tracked) and the arm's
configuration psi (from the encoders). The model (models.kinematics, forward kinematics) gives
the centre c_w(psi) and axis a_w(psi) in {w}; we solve c_w = R c_l + t, a_w = R a_l. The
marker's roll is not used (it is only known modulo the pattern's period).

1. Closed form: Kabsch/Umeyama on the centres (scipy Rotation.align_vectors), then each axis's
   sign fixed against the model's (the sleeve is symmetric under a half turn).
2. Robust refinement: scipy least_squares with a soft-L1 loss over the 6 pose parameters and,
   with ``estimate_arm`` (default), the arm's observable model errors (:class:`ArmCorrection`):
   the bend gains g1, g2 and segment 2's plane offset o2 (theta_t -> g_t theta_t, delta_2 ->
   delta_2 + o2), the exposed stem's bend zeta * theta_1 in segment 1's plane, and the play of
   each actuator's backlash (each visit's last motion direction per actuator is known from the
   side it was approached from: the output lags the encoder by half the play). Segment 1's
   plane offset o1 is NOT observable: with a straight stem along z_w it turns the whole arm about
   z_w, exactly like a rotation of the camera about z_w (or an offset of the phi encoder); it
   ends up in world_T_left's rotation about z_w and must come from homing the phi axis. A tip
   load bends the arm differently in every pose and is not modelled: it stays in the residuals.

Residuals are scaled by the tracker's accuracy (centre 0.05 mm, axis 0.2 deg), so the loss's
knee is at about 3 sigma. Units: metres, radians.

Any arm (a format-2 robot file, models.arm_spec.ArmSpec): the same correction sized to the arm
(:meth:`ArmCorrection.for_arm`), as the simulated true arm (sim/plant.py) errs: a bend gain per
segment, a plane offset per segment but the first (segment 1's is a turn about z_w, as above:
every format-2 stem joint turns about or feeds along z_w; a planar segment's offset turns its
fixed plane), the stem coupling where the stem feeds (a prismatic joint: the exposed stem's length
varies; without one it has no length and no effect) and the half play of every actuator. What is
not separable: segment 1's plane offset (in world_T_left's turn about z_w); for tendon segments
the plays of a segment's tendons only as far as the visits' motion signs differ (the true arm's
output is the least-squares psi of its tendons, so a play common to all of a segment's tendons
moves nothing; such a play fits to anything and is reported, not trusted); a tip load (stays in
the residuals). ``estimate_arm=False`` fits world_T_left alone (rigid).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_actuation import arm_actuators, arm_psi_from_actuators
from wristmark.models.arm_spec import Arm, ArmSpec, actuator_units
from wristmark.models.constant_curvature import rot_z, segment_transform
from wristmark.models.errors import InputError
from wristmark.models.kinematics import forward_kinematics

Array = NDArray[np.float64]
SIGMA_CENTRE = 5e-5  # [m] centre accuracy of the stereo marker pose (NOTES: ~29 um median)
SIGMA_AXIS = np.radians(0.2)  # [rad] axis accuracy (NOTES: ~0.19 deg median)
MIN_POSES = 4
MIN_POSES_ARM = 8
OUTLIER_SIGMAS = 8.0  # an observation this many sigmas off after the first solve is dropped (at most 25 %)
# starts of the bend gains' fit, as offsets from 1 (real arms' gains are below 1: tendon stretch,
# friction): the cost is not smooth (each play's dead band clips), and with tendon3's plant the
# nominal start stopped in a local minimum 0.6 mm from the true camera (2026-12-03)
GAIN_STARTS = (0.0, -0.05, -0.1)
_EXACT_COST = 1e-10  # [sigma^2] a fit's cost this low is exact (simulated, noise-free observations)
_PLAY_SCALE = np.array([1e-2, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4])  # [rad, m, ...] typical half plays (scaling)


@dataclass(frozen=True)
class RegistrationPose:
    """One observation: configuration psi (from the encoders) [rad, m, rad, rad, rad, rad], the
    marker centre (3,) [m] and unit z axis (3,) in {ll}, a name for messages, and the sign of
    each actuator's last motion before the observation (m,) (zeros: unknown). Any arm (an
    ArmSpec) may also give ``approach_move``, each actuator's last move [rad or m] (from the
    approach point to psi) and ``prior_sign``, the sign of its move into the approach point:
    then a move shorter than the play leaves the output inside its dead band, as it truly does
    (a tendon whose angle lies across the approach's bend moves little). ``path`` (any arm): the
    actuator targets (k, m) [rad or m] of every move since the first visit's approach point, in
    the order visited, ending with this visit's; each output then follows the play operator along
    all of them (a move shorter than the full play keeps the lag the moves before it left: the
    last two moves do not tell it when the plays are as wide as the approach's tendon moves)."""

    psi: Array
    centre_left: Array
    axis_left: Array
    name: str = ""
    motion_sign: Array = field(default_factory=lambda: np.zeros(6))
    approach_move: Array | None = None
    prior_sign: Array | None = None
    path: Array | None = None

    @property
    def play_unknown(self) -> bool:
        """Whether the outputs' places in their dead bands before this visit's moves are unknown
        (any arm: the first visit, whose prior move is not known, ``prior_sign`` all zeros)."""
        return self.prior_sign is not None and not np.any(self.prior_sign)


@dataclass(frozen=True)
class ArmCorrection:
    """Observable model errors of the arm: bend gains per segment [-], segment 2's plane offset
    [rad] (the reference arm), stem coupling zeta [-], the half play of each actuator's backlash
    [rad or m each, in the arm's actuator order], and for any arm (an ArmSpec) ``plane_offset``,
    one per segment [rad] (the first always 0: not observable)."""

    bend_gain: tuple[float, ...] = (1.0, 1.0)
    plane_offset_2: float = 0.0
    stem_coupling: float = 0.0
    half_play: tuple[float, ...] = (0.0,) * 6
    plane_offset: tuple[float, ...] = ()

    @classmethod
    def for_arm(cls, params: Arm) -> ArmCorrection:
        """No correction, sized to ``params`` (N segments, m actuators)."""
        if not isinstance(params, ArmSpec):
            return cls()
        return cls(bend_gain=(1.0,) * len(params.segments), half_play=(0.0,) * params.m,
                   plane_offset=(0.0,) * len(params.segments))

    def is_identity(self) -> bool:
        """Whether it corrects nothing (the model's forward kinematics as they are)."""
        return (all(g == 1.0 for g in self.bend_gain) and self.plane_offset_2 == 0.0 and self.stem_coupling == 0.0
                and not any(self.half_play) and not any(self.plane_offset))

    def marker_frame(self, params: Arm, psi: Array, motion_sign: Array, approach_move: Array | None = None,
                     prior_sign: Array | None = None, path: Array | None = None) -> Array:
        """The model's 4x4 pose of {wm} in {w} with the corrections applied (any arm: each
        segment's gain and plane offset, the stem bent in segment 1's plane, the plays, as
        sim/plant.py's true arm; with ``approach_move`` and ``prior_sign``, RegistrationPose's,
        each output's lag after its last two moves through the dead band; with ``path``, after
        all the moves of the path)."""
        q = np.array(psi, float)
        if self.is_identity():
            return forward_kinematics(params, q).T_world_marker
        if isinstance(params, ArmSpec):
            return self._spec_marker_frame(params, q, motion_sign, approach_move, prior_sign, path)
        if any(self.half_play):
            a = actuators_from_psi(params, q) - np.asarray(self.half_play) * motion_sign
            q = psi_from_actuators(params, a, q)
        q[2] *= self.bend_gain[0]
        q[4] *= self.bend_gain[1]
        q[5] += self.plane_offset_2
        T = forward_kinematics(params, q).T_world_marker
        if self.stem_coupling:  # the straight stem (Rz(phi), d along z) replaced by its bent arc
            S = np.eye(4)
            S[:3, :3] = rot_z(q[0])
            straight = S.copy()
            straight[2, 3] = q[1]
            T = S @ segment_transform(q[1], self.stem_coupling * q[2], q[3]) @ np.linalg.inv(straight) @ T
        return T

    def _spec_marker_frame(self, spec: ArmSpec, q: Array, motion_sign: Array, approach_move: Array | None,
                           prior_sign: Array | None, path: Array | None = None) -> Array:
        """:meth:`marker_frame` of any arm (sim/plant.py's TruePlant._bend_any and _chain without the tip load)."""
        self._check_size(spec)
        if any(self.half_play):
            h = np.abs(np.asarray(self.half_play))
            if path is not None and len(path) > 0:  # the play operator along every move (sim/plant.py)
                lag = path_lags([np.asarray(path, float)], h)[0]
            elif approach_move is not None and prior_sign is not None:  # output - motor after the two moves
                lag = np.clip(-prior_sign * h - approach_move, -h, h)
            else:
                lag = -h * motion_sign
            q = psi_from_actuators(spec, actuators_from_psi(spec, q) + lag, q)
        return self._spec_bent_frame(spec, q)

    def _check_size(self, spec: ArmSpec) -> None:
        n_seg = len(spec.segments)
        if len(self.bend_gain) != n_seg or len(self.half_play) != spec.m or len(self.plane_offset) != n_seg:
            raise InputError(f"an arm correction of {spec.name} needs {n_seg} bend gains and plane offsets and "
                             f"{spec.m} plays (ArmCorrection.for_arm)")

    def _spec_bent_frame(self, spec: ArmSpec, q_out: Array) -> Array:
        """The 4x4 pose of {wm} in {w} of any arm whose outputs (past the plays) are at the
        configuration ``q_out``: each segment's gain and plane offset, the stem bent in segment 1's plane."""
        q = np.array(q_out, float)
        if any(sg.planar is not None and o for sg, o in zip(spec.segments, self.plane_offset)):
            spec = replace(spec, segments=tuple(replace(sg, planar=sg.planar + o) if sg.planar is not None else sg
                                                for sg, o in zip(spec.segments, self.plane_offset)))
        for t, (ti, di) in enumerate(zip(spec.theta_index, spec.delta_index)):
            q[ti] *= self.bend_gain[t]
            if di is not None:
                q[di] += self.plane_offset[t]
        bend = self.stem_coupling * float(q[spec.theta_index[0]])
        return forward_kinematics(spec, q, stem_bend=bend).T_world_marker

    def spec_marker_frames(self, spec: ArmSpec, psi: Array, lags: Array) -> list[Array]:
        """:meth:`marker_frame` of any arm at each configuration of ``psi`` (K, n) whose outputs lag
        their motors by ``lags`` (K, m) [rad or m]: the plays of all K at once."""
        self._check_size(spec)
        q = np.asarray(psi, float)
        if any(self.half_play):
            q = arm_psi_from_actuators(spec, arm_actuators(spec, q) + lags, q)
        return [self._spec_bent_frame(spec, qk) for qk in q]


@dataclass
class RegistrationResult:
    """world_T_left (4x4, metres), residual RMS of the centres [m], per-pose residuals (centre [m],
    axis [rad]), the arm correction estimated alongside, the closed-form start and the poses
    dropped as outliers (more than OUTLIER_SIGMAS off after a first robust solve); rms_m covers
    the poses kept."""

    world_T_left: Array
    rms_m: float
    centre_residuals_m: Array
    axis_residuals_rad: Array
    arm: ArmCorrection
    closed_form: Array
    names: list[str] = field(default_factory=list)
    outliers: list[str] = field(default_factory=list)


def path_lags(paths: list[Array], half_play: Array) -> Array:
    """Output - motor (n, m) at the end of each of ``n`` paths of actuator targets (k_i, m), the
    output starting at the path's first target and following the play operator of half width
    ``half_play`` (m,) (as sim/plant.py's true arm, whose motors reach each target). All paths
    at once: each padded with its last target (a repeated target moves nothing)."""
    k = max(len(p) for p in paths)
    P = np.array([np.concatenate([p, np.repeat(p[-1:], k - len(p), axis=0)]) for p in paths])  # (n, k, m)
    out = P[:, 0].copy()
    for j in range(1, k):
        out = np.minimum(np.maximum(out, P[:, j] - half_play), P[:, j] + half_play)
    return out - P[:, -1]


def _model(params: Arm, poses: list[RegistrationPose], arm: ArmCorrection) -> tuple[Array, Array]:
    if (isinstance(params, ArmSpec) and any(arm.half_play) and poses
            and all(p.path is not None and len(p.path) for p in poses)):
        lags = path_lags([np.asarray(p.path, float) for p in poses], np.abs(np.asarray(arm.half_play, float)))
        frames = arm.spec_marker_frames(params, np.array([p.psi for p in poses], float), lags)
    else:
        frames = [arm.marker_frame(params, p.psi, p.motion_sign, p.approach_move, p.prior_sign, p.path)
                  for p in poses]
    return np.array([T[:3, 3] for T in frames]), np.array([T[:3, 2] for T in frames])


def _transform(R: Array, t: Array) -> Array:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def check_spread(centres_world: Array, min_extent: float = 0.003, min_ratio: float = 0.08) -> None:
    """Refuse degenerate pose sets: too few, or centres (N, 3) [m] nearly on a point or a line."""
    n = len(centres_world)
    if n < MIN_POSES:
        raise InputError(f"registration needs at least {MIN_POSES} tracked poses, got {n}: use more --poses")
    s = np.linalg.svd(centres_world - centres_world.mean(axis=0), compute_uv=False) / np.sqrt(n)
    if s[0] < min_extent:
        raise InputError(f"the marker centres span only {1000 * s[0]:.2f} mm (RMS): spread the poses over the "
                         "workspace (need >= 3 mm)")
    if s[1] < min_ratio * s[0]:
        raise InputError(f"the marker centres are nearly collinear (spread {1000 * s[1]:.2f} mm across vs "
                         f"{1000 * s[0]:.2f} mm along): choose poses off one line")


def closed_form(centres_left: Array, centres_world: Array) -> Array:
    """Kabsch/Umeyama (no scale): the 4x4 world_T_left that best maps the {ll} centres onto {w}."""
    ml, mw = centres_left.mean(axis=0), centres_world.mean(axis=0)
    rot, _ = Rotation.align_vectors(centres_world - mw, centres_left - ml)
    R = rot.as_matrix()
    return _transform(R, mw - R @ ml)


def solve_registration(params: Arm, poses: list[RegistrationPose], estimate_arm: bool = True,
                       loss: str = "soft_l1") -> RegistrationResult:
    """world_T_left from the observations (see the module docstring). InputError on too few or
    degenerate poses."""
    if estimate_arm and len(poses) < MIN_POSES_ARM:
        raise InputError(f"estimating the arm's gains with the registration needs at least {MIN_POSES_ARM} "
                         f"tracked poses, got {len(poses)}: use more --poses (or --rigid-arm)")
    cl = np.array([p.centre_left for p in poses], float).reshape(-1, 3)
    al = np.array([p.axis_left for p in poses], float).reshape(-1, 3)
    al /= np.linalg.norm(al, axis=1, keepdims=True)
    cw, aw = _model(params, poses, ArmCorrection.for_arm(params))
    check_spread(cw)
    W0 = closed_form(cl, cw)
    al = al * np.sign(np.sum((al @ W0[:3, :3].T) * aw, axis=1, keepdims=True) + 1e-12)

    backlash = estimate_arm and any(np.any(p.motion_sign != 0) for p in poses)
    unpack_arm, n_arm = _arm_unpacker(params, backlash) if estimate_arm else (None, 0)

    def pose_of(x: Array) -> tuple[Array, Array]:
        return Rotation.from_rotvec(x[:3]).as_matrix(), x[3:6]

    def unpack(x: Array) -> tuple[Array, Array, ArmCorrection]:
        arm = unpack_arm(x[6:]) if unpack_arm is not None else ArmCorrection.for_arm(params)
        return *pose_of(x), arm

    # with the plays estimated, a visit whose outputs' place in the dead band is unknown (any arm's
    # first visit) is not fitted: a lag guessed wrong by up to a play pulls the camera along the
    # fit's weakly observed gains (tendon3's plant: 0.8 mm), like a wrong observation
    fit = np.array([not (backlash and p.play_unknown) for p in poses]) if isinstance(params, ArmSpec) \
        else np.ones(len(poses), bool)
    if fit.sum() < (MIN_POSES_ARM if estimate_arm else MIN_POSES):
        fit[:] = True
    keep = fit.copy()

    last: dict[bytes, tuple[Array, Array]] = {}

    def model(x: Array) -> tuple[Array, Array]:
        """The model's centres and axes in {w} at x's arm correction; the last kept: the Jacobian's
        six steps of the camera's pose leave the arm as it was (a third of tendon3's model calls)."""
        key = x[6:].tobytes()
        if key not in last:
            last.clear()
            last[key] = _model(params, poses, unpack(x)[2])
        return last[key]

    def residuals(x: Array) -> Array:
        R, t = pose_of(x)
        mw, ma = model(x)
        rc = (cl @ R.T + t - mw) / SIGMA_CENTRE
        ra = (al @ R.T - ma) / SIGMA_AXIS
        return np.concatenate([rc[keep].ravel(), ra[keep].ravel()])

    def errors(x: Array) -> tuple[Array, Array]:
        R, t = pose_of(x)
        mw, ma = model(x)
        return (np.linalg.norm(cl @ R.T + t - mw, axis=1),
                np.arccos(np.clip(np.sum((al @ R.T) * ma, axis=1), -1.0, 1.0)))

    x0 = np.concatenate([Rotation.from_matrix(W0[:3, :3]).as_rotvec(), W0[:3, 3], np.zeros(n_arm)])
    best = None
    n_seg = len(params.segments) if isinstance(params, ArmSpec) else 2
    for g in GAIN_STARTS if n_arm else (0.0,):  # the plays' kinks leave local minima along the gains
        x0[6:6 + n_seg] = g
        sol = least_squares(residuals, x0, loss=loss, f_scale=3.0, x_scale="jac", method="trf")
        if best is None or sol.cost < best.cost:
            best = sol
        if best.cost < _EXACT_COST:  # the data fitted exactly: no start does better
            break
    assert best is not None
    x = best.x
    if n_arm and best.cost >= _EXACT_COST:  # to the bottom of the best start's basin (one basin: one result)
        x = least_squares(residuals, x, loss=loss, f_scale=3.0, x_scale="jac", method="trf", ftol=1e-12, xtol=1e-12,
                          gtol=1e-12).x
    dc, da = errors(x)
    bad = ((dc > OUTLIER_SIGMAS * SIGMA_CENTRE) | (da > OUTLIER_SIGMAS * SIGMA_AXIS)) & fit
    if 0 < bad.sum() <= 0.25 * len(poses):  # a few wrong observations: solve again without them
        keep = fit & ~bad
        x = least_squares(residuals, x, loss=loss, f_scale=3.0, x_scale="jac", method="trf").x
        dc, da = errors(x)
    R, t, arm = unpack(x)
    names = [p.name or str(i) for i, p in enumerate(poses)]
    return RegistrationResult(_transform(R, t), float(np.sqrt(np.mean(dc[keep] ** 2))), dc, da, arm, W0, names,
                              [n for n, k, f in zip(names, keep, fit) if f and not k])


def _arm_unpacker(params: Arm, backlash: bool) -> tuple[Callable[[Array], ArmCorrection], int]:
    """The arm correction's free parameters (offsets from no correction, scaled) -> ArmCorrection,
    and their count: the reference arm's g1, g2, o2, zeta (and 6 plays); any arm's N gains, N - 1
    plane offsets (segments 2..N), zeta where the stem feeds, and m plays (module docstring)."""
    if not isinstance(params, ArmSpec):
        def reference(y: Array) -> ArmCorrection:
            play = tuple(y[4:10] * _PLAY_SCALE) if backlash else (0.0,) * 6
            return ArmCorrection((1.0 + y[0], 1.0 + y[1]), y[2], y[3], play)
        return reference, 10 if backlash else 4
    n_seg, m = len(params.segments), params.m
    feeds = any(j.joint.startswith("prismatic") for j in params.stem)
    scale = np.array([1e-2 if u == "rad" else 1e-4 for u in actuator_units(params)])

    def any_arm(y: Array) -> ArmCorrection:
        k = 2 * n_seg - 1
        zeta = float(y[k]) if feeds else 0.0
        k += int(feeds)
        play = tuple(y[k:k + m] * scale) if backlash else (0.0,) * m
        return ArmCorrection(tuple(1.0 + y[:n_seg]), 0.0, zeta, play, (0.0, *y[n_seg:2 * n_seg - 1]))
    return any_arm, 2 * n_seg - 1 + int(feeds) + (m if backlash else 0)


def transform_error(A: Array, B: Array) -> tuple[float, float]:
    """Translation [m] and rotation [rad] between two 4x4 poses."""
    D = np.linalg.inv(np.asarray(A, float)) @ np.asarray(B, float)
    return float(np.linalg.norm(A[:3, 3] - B[:3, 3])), float(Rotation.from_matrix(D[:3, :3]).magnitude())
