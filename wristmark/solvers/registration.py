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

Any arm (a format-2 robot file, models.arm_spec.ArmSpec): the arm correction above is the
reference arm's, so the fit is rigid (``estimate_arm=False``): world_T_left alone from the
model's marker poses (models.kinematics.forward_kinematics of the ArmSpec).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.constant_curvature import rot_z, segment_transform
from wristmark.models.errors import InputError
from wristmark.models.kinematics import forward_kinematics

Array = NDArray[np.float64]
SIGMA_CENTRE = 5e-5  # [m] centre accuracy of the stereo marker pose (NOTES: ~29 um median)
SIGMA_AXIS = np.radians(0.2)  # [rad] axis accuracy (NOTES: ~0.19 deg median)
MIN_POSES = 4
MIN_POSES_ARM = 8
OUTLIER_SIGMAS = 8.0  # an observation this many sigmas off after the first solve is dropped (at most 25 %)
_PLAY_SCALE = np.array([1e-2, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4])  # [rad, m, ...] typical half plays (scaling)


@dataclass(frozen=True)
class RegistrationPose:
    """One observation: configuration psi (from the encoders) [rad, m, rad, rad, rad, rad], the
    marker centre (3,) [m] and unit z axis (3,) in {ll}, a name for messages, and the sign of
    each actuator's last motion before the observation (6,) (zeros: unknown)."""

    psi: Array
    centre_left: Array
    axis_left: Array
    name: str = ""
    motion_sign: Array = field(default_factory=lambda: np.zeros(6))


@dataclass(frozen=True)
class ArmCorrection:
    """Observable model errors of the arm: bend gains [-], segment 2's plane offset [rad], stem
    coupling zeta [-] and the half play of each actuator's backlash [rad, m, m, m, m, m]."""

    bend_gain: tuple[float, float] = (1.0, 1.0)
    plane_offset_2: float = 0.0
    stem_coupling: float = 0.0
    half_play: tuple[float, ...] = (0.0,) * 6

    def marker_frame(self, params: Arm, psi: Array, motion_sign: Array) -> Array:
        """The model's 4x4 pose of {wm} in {w} with the corrections applied (none: any arm's
        forward kinematics; the corrections model the reference arm's RobotParams only)."""
        q = np.array(psi, float)
        if self == ArmCorrection() or isinstance(params, ArmSpec):
            if isinstance(params, ArmSpec) and self != ArmCorrection():
                raise InputError("the arm correction (bend gains, stem coupling, play) models the reference arm "
                                 "only: fit a format-2 arm rigidly (--rigid-arm)")
            return forward_kinematics(params, q).T_world_marker
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


def _model(params: Arm, poses: list[RegistrationPose], arm: ArmCorrection) -> tuple[Array, Array]:
    frames = [arm.marker_frame(params, p.psi, p.motion_sign) for p in poses]
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
    degenerate poses, or on ``estimate_arm`` for any arm but the reference arm."""
    if estimate_arm and isinstance(params, ArmSpec):
        raise InputError("the arm correction (bend gains, stem coupling, play) models the reference arm only: "
                         "fit a format-2 arm rigidly (--rigid-arm)")
    if estimate_arm and len(poses) < MIN_POSES_ARM:
        raise InputError(f"estimating the arm's gains with the registration needs at least {MIN_POSES_ARM} "
                         f"tracked poses, got {len(poses)}: use more --poses (or --rigid-arm)")
    cl = np.array([p.centre_left for p in poses], float).reshape(-1, 3)
    al = np.array([p.axis_left for p in poses], float).reshape(-1, 3)
    al /= np.linalg.norm(al, axis=1, keepdims=True)
    cw, aw = _model(params, poses, ArmCorrection())
    check_spread(cw)
    W0 = closed_form(cl, cw)
    al = al * np.sign(np.sum((al @ W0[:3, :3].T) * aw, axis=1, keepdims=True) + 1e-12)

    backlash = estimate_arm and any(np.any(p.motion_sign != 0) for p in poses)

    def unpack(x: Array) -> tuple[Array, Array, ArmCorrection]:
        arm = ArmCorrection()
        if estimate_arm:
            play = tuple(x[10:16] * _PLAY_SCALE) if backlash else (0.0,) * 6
            arm = ArmCorrection((1.0 + x[6], 1.0 + x[7]), x[8], x[9], play)
        return Rotation.from_rotvec(x[:3]).as_matrix(), x[3:6], arm

    keep = np.ones(len(poses), bool)

    def residuals(x: Array) -> Array:
        R, t, arm = unpack(x)
        mw, ma = _model(params, poses, arm)
        rc = (cl @ R.T + t - mw) / SIGMA_CENTRE
        ra = (al @ R.T - ma) / SIGMA_AXIS
        return np.concatenate([rc[keep].ravel(), ra[keep].ravel()])

    def errors(x: Array) -> tuple[Array, Array]:
        R, t, arm = unpack(x)
        mw, ma = _model(params, poses, arm)
        return (np.linalg.norm(cl @ R.T + t - mw, axis=1),
                np.arccos(np.clip(np.sum((al @ R.T) * ma, axis=1), -1.0, 1.0)))

    n_arm = (10 if backlash else 4) if estimate_arm else 0
    x = np.concatenate([Rotation.from_matrix(W0[:3, :3]).as_rotvec(), W0[:3, 3], np.zeros(n_arm)])
    x = least_squares(residuals, x, loss=loss, f_scale=3.0, x_scale="jac", method="trf").x
    dc, da = errors(x)
    bad = (dc > OUTLIER_SIGMAS * SIGMA_CENTRE) | (da > OUTLIER_SIGMAS * SIGMA_AXIS)
    if 0 < bad.sum() <= 0.25 * len(poses):  # a few wrong observations: solve again without them
        keep = ~bad
        x = least_squares(residuals, x, loss=loss, f_scale=3.0, x_scale="jac", method="trf").x
        dc, da = errors(x)
    R, t, arm = unpack(x)
    names = [p.name or str(i) for i, p in enumerate(poses)]
    return RegistrationResult(_transform(R, t), float(np.sqrt(np.mean(dc[keep] ** 2))), dc, da, arm, W0, names,
                              [n for n, k in zip(names, keep) if not k])


def transform_error(A: Array, B: Array) -> tuple[float, float]:
    """Translation [m] and rotation [rad] between two 4x4 poses."""
    D = np.linalg.inv(np.asarray(A, float)) @ np.asarray(B, float)
    return float(np.linalg.norm(A[:3, 3] - B[:3, 3])), float(Rotation.from_matrix(D[:3, :3]).magnitude())
