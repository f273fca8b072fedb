"""Identification: fit how the real arm differs from its robot file, from tracked tip positions
and the actuators' encoder history (docs/identification.md).

The data (:class:`ExcitationData`): every control cycle's encoder readings [rad, m, ...] and the
targets sent, and at some cycles (the arm at rest after a move) the tip measured in {w} [m]. The
forward model is the plant's (models/plant_map.py): each actuator's output is a play operator of
width b_j run through the encoder readings (from the first, where the output is taken to sit on
the motor: the excitation's first moves wipe that guess out), the nominal inverse actuation map
gives the backbones' configuration, then the bend gains, plane offsets, stem coupling and tip
load bend it. The static parameters are fitted by ``scipy.optimize.least_squares`` with a robust
(soft-L1) loss over the measured tips; the lag from the targets and the encoders alone
(solvers/play_probe_fit.py ``fit_motor_lag``, the median over the actuators: the plant file has
one lag). Standard errors come from the Jacobian at the solution (s^2 (J^T J)^-1); parameters
that the data cannot tell apart are found from the correlations and the smallest singular
values of the column-normalised Jacobian, and listed with the ones that cannot be separated by
construction (the first plane offset against the stem-rotation encoder's zero; the tip force
against the segments' stiffness without a known load: the stiffness is kept at the file's and
the force fitted as the load that bends the arm so). With a known load on some samples
(``ExcitationData.loads``) the segments' stiffness is fitted too.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from wristmark.models.actuation import psi_from_actuators
from wristmark.models.arm_spec import Arm, ArmSpec, arm_size
from wristmark.models.errors import InputError
from wristmark.models.plant_map import plant_tip, true_arm
from wristmark.models.plant_params import PlantParams
from wristmark.solvers.play_probe_fit import fit_motor_lag

Array = NDArray[np.float64]
__all__ = ["ExcitationData", "Identification", "identify", "parameter_names", "play_outputs", "pack", "unpack",
           "predicted_tips"]

CORRELATED = 0.97  # |correlation| above which two fitted parameters are reported as not separated
WEAK = 1e-3  # a normalised singular value below this: a direction the data do not determine
FORCE_SCALE = 0.1  # [N] the fit's unit of the tip force
ALWAYS_NOT_SEPARABLE = (
    "plane_offset[0] ~ the stem-rotation encoder's zero (a turn of segment 1's plane and of the stem joint "
    "look alike at the tip; the fit gives it all to plane_offset[0], as registration found)",
    "tip_force ~ segment_stiffness (without a known load only the load's bend is seen: the stiffness is kept at "
    "the file's and the force fitted)",
)
WITH_CAMERA_NOT_SEPARABLE = (
    "plane_offset[0] ~ the camera's turn about z_w ~ the stem-rotation encoder's zero (all three turn the arm "
    "about z_w alike: plane_offset[0] is held at the start's value and the turn is in world_T_left, as "
    "registration does)",
    ALWAYS_NOT_SEPARABLE[1],
)
CAMERA_NAMES = ("camera_rot[0]", "camera_rot[1]", "camera_rot[2]", "camera_shift[0]", "camera_shift[1]",
                "camera_shift[2]")
SHIFT_SCALE = 1e-3  # [m] the fit's unit of the camera's shift


@dataclass(frozen=True)
class ExcitationData:
    """An excitation's record: per control cycle k the time ``times[k]`` [s], the encoders
    ``encoders[k]`` [rad, m, ...] read then and the targets ``targets[k]`` sent just after
    (actuator units); ``sample_index[i]`` the cycle at which the tip ``tips[i]`` in {w} [m] was
    measured (NaN rows: not measured), ``psi_hint[i]`` the configuration commanded then (for the
    bending planes at theta ~ 0); ``restarts`` the cycles at which a fresh arm started (its plays'
    outputs then on their motors, as at the first cycle: e.g. each phase of an ``experiment`` run)."""

    times: Array
    encoders: Array
    targets: Array
    sample_index: NDArray[np.int_]
    tips: Array
    psi_hint: Array
    meta: dict[str, object] = field(default_factory=dict)
    restarts: tuple[int, ...] = ()
    loads: Array | None = None  # per sample a known tip force added to the arm's own [N] in {w} (None: none)

    def loaded(self) -> bool:
        """Whether some samples carry a known load and others another (the stiffness is then seen)."""
        return self.loads is not None and bool(np.ptp(np.asarray(self.loads, float), axis=0).max() > 0)

    def check(self, arm: Arm) -> None:
        """InputError naming what does not fit ``arm`` or each other."""
        m = arm_size(arm)[1]
        k = self.times.shape[0]
        if self.encoders.shape != (k, m) or self.targets.shape != (k, m):
            raise InputError(f"excitation: encoders and targets must be ({k}, {m}) arrays (one row per cycle, one "
                             f"column per actuator), got {self.encoders.shape} and {self.targets.shape}")
        if self.tips.shape != (self.sample_index.size, 3) or self.psi_hint.shape[0] != self.sample_index.size:
            raise InputError("excitation: one tip (3 values) and one configuration per sample")
        if self.sample_index.size and (self.sample_index.min() < 0 or self.sample_index.max() >= k):
            raise InputError(f"excitation: sample indices must be in [0, {k})")
        ok = int(np.isfinite(self.tips).all(axis=1).sum())
        if ok < 8:
            raise InputError(f"excitation: {ok} measured tips; the fit needs 8 or more")


@dataclass(frozen=True)
class Identification:
    """A fit: the identified plant (plant-file keys, SI units), the RMS of the tip residual [m]
    over the ``poses`` measured, each fitted parameter's value and standard error (by the
    plant-file key and index, e.g. ``backlash[3]``), and what could not be separated."""

    plant: PlantParams
    rms_m: float
    poses: int
    values: dict[str, float]
    std_errors: dict[str, float]
    not_separable: list[str]
    lag_per_actuator: list[float]
    world_correction: Array | None = None  # with the camera fitted: {w} -> {w} (4x4) applied to world_T_left


def parameter_names(arm: Arm) -> list[str]:
    """The fitted parameters in the fit's order: bend_gain[t], plane_offset[t] (segments that bend
    in any plane), stem_coupling, backlash[j], tip_force[x, y, z]."""
    segs, m = _segments(arm), arm_size(arm)[1]
    names = [f"bend_gain[{t}]" for t in range(segs)]
    names += [f"plane_offset[{t}]" for t in range(segs)]
    names += ["stem_coupling"] + [f"backlash[{j}]" for j in range(m)] + [f"tip_force[{i}]" for i in range(3)]
    return names


def _segments(arm: Arm) -> int:
    return len(arm.segments) if isinstance(arm, ArmSpec) else 2


def pack(arm: Arm, plant: PlantParams, play_unit: Array) -> Array:
    """The fit's vector of ``plant`` (plays in units of ``play_unit``, the force in FORCE_SCALE)."""
    p = plant.for_arm(_segments(arm), arm_size(arm)[1])
    return np.concatenate([p.bend_gain, p.plane_offset, [p.stem_coupling],
                           np.asarray(p.backlash, float) / play_unit, np.asarray(p.tip_force, float) / FORCE_SCALE])


def unpack(arm: Arm, x: Array, play_unit: Array, base: PlantParams) -> PlantParams:
    """The plant of the fit's vector ``x`` (the keys not fitted from ``base``)."""
    s, m = _segments(arm), arm_size(arm)[1]
    i = 0

    def take(n: int) -> Array:
        nonlocal i
        out = np.asarray(x[i:i + n], float)
        i += n
        return out

    g, o, z = take(s), take(s), take(1)[0]
    b = take(m) * play_unit
    f = take(3) * FORCE_SCALE
    return dataclasses.replace(base, bend_gain=tuple(map(float, g)), plane_offset=tuple(map(float, o)),
                               stem_coupling=float(z), backlash=tuple(map(float, np.maximum(b, 0.0))),
                               tip_force=(float(f[0]), float(f[1]), float(f[2])))


def play_outputs(encoders: Array, plays: Array, restarts: tuple[int, ...] = ()) -> Array:
    """The play operators' outputs (K, m) of widths ``plays`` (m,) driven by the encoder rows
    ``encoders`` (K, m), each output starting on its motor (at the first row and at the rows
    ``restarts``)."""
    enc = np.asarray(encoders, float)
    half = 0.5 * np.maximum(np.asarray(plays, float), 0.0)
    out = np.empty_like(enc)
    o = enc[0].copy()
    fresh = set(restarts)
    for k in range(enc.shape[0]):
        if k in fresh:
            o = enc[k].copy()
        o = np.clip(o, enc[k] - half, enc[k] + half)
        out[k] = o
    return out


def predicted_tips(arm: Arm, plant: PlantParams, data: ExcitationData) -> Array:
    """The tips in {w} [m] (N, 3) the arm with ``plant``'s errors reaches at the data's samples."""
    outs = play_outputs(data.encoders, np.asarray(plant.backlash, float), data.restarts)[data.sample_index]
    arm_t = true_arm(arm, plant)
    if data.loads is None:
        return np.array([plant_tip(arm_t, plant, psi_from_actuators(arm, a, delta_hint=h))
                         for a, h in zip(outs, data.psi_hint)])
    own = np.asarray(plant.tip_force, float)
    loaded = {tuple(f): dataclasses.replace(plant, tip_force=(float(own[0] + f[0]), float(own[1] + f[1]),
                                                              float(own[2] + f[2])))
              for f in np.asarray(data.loads, float)}
    return np.array([plant_tip(arm_t, loaded[tuple(f)], psi_from_actuators(arm, a, delta_hint=h))
                     for a, h, f in zip(outs, data.psi_hint, np.asarray(data.loads, float))])


def identify(arm: Arm, data: ExcitationData, play_unit: Array, start: PlantParams | None = None,
             loss_scale: float = 1e-4, camera: bool = False) -> Identification:
    """Fit the plant-file parameters of ``arm`` to the excitation ``data`` (module docstring).

    play_unit: per actuator the play's order of magnitude [rad, m, ...] (e.g. the controller's
    backlash_play_max; the fit's scale and a bound of 3x it); start: the first guess (default the
    ideal arm); loss_scale: the soft-L1 loss's knee [m] (residuals well above it count less).
    camera: fit where the camera is as well (identification and registration from one
    excitation): a rigid correction C of {w} with the measured tips taken as C applied to them
    (so the registered world_T_left is C @ the one they were measured with), started from the
    centres' closed-form alignment (Kabsch) to the start's model; plane_offset[0] is then held
    at the start's value (its turn about z_w is the camera's)."""
    data.check(arm)
    s, m = _segments(arm), arm_size(arm)[1]
    unit = np.asarray(play_unit, float)
    if unit.shape != (m,) or not np.all(unit > 0):
        raise InputError(f"identification: the play unit must be {m} values > 0, got {unit.tolist()}")
    base = (start or PlantParams()).for_arm(s, m)
    ok = np.isfinite(data.tips).all(axis=1)
    sub = dataclasses.replace(data, sample_index=data.sample_index[ok], tips=data.tips[ok], psi_hint=data.psi_hint[ok],
                              loads=None if data.loads is None else np.asarray(data.loads, float)[ok])
    stiff = sub.loaded()  # a known load on some samples: the stiffness is seen
    x0 = pack(arm, base, unit)
    x0[2 * s + 1:2 * s + 1 + m] = np.clip(x0[2 * s + 1:2 * s + 1 + m], 0.0, 3.0)
    lo = np.concatenate([np.full(s, 0.5), np.full(s, -0.5), [0.0], np.zeros(m), np.full(3, -10.0)])
    hi = np.concatenate([np.full(s, 1.5), np.full(s, 0.5), [1.0], np.full(m, 3.0), np.full(3, 10.0)])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    names = parameter_names(arm)
    scale = np.concatenate([np.ones(2 * s + 1), unit, np.full(3, FORCE_SCALE)])
    free = np.ones(x0.size, bool)
    if stiff:
        k0 = np.asarray(base.segment_stiffness, float)
        x0, lo, hi = np.r_[x0, k0], np.r_[lo, np.full(s, 0.02)], np.r_[hi, np.full(s, 5.0)]
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        names += [f"segment_stiffness[{t}]" for t in range(s)]
        scale, free = np.r_[scale, np.ones(s)], np.r_[free, np.ones(s, bool)]
    n_plant = x0.size
    if camera:
        free[s] = False  # plane_offset[0]: the camera's turn about z_w
        c0 = _camera_start(predicted_tips(arm, base, sub), sub.tips)
        x0, lo, hi = np.r_[x0, c0], np.r_[lo, np.full(3, -0.5), np.full(3, -100.0)], np.r_[hi, np.full(3, 0.5),
                                                                                          np.full(3, 100.0)]
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        names += list(CAMERA_NAMES)
        scale = np.r_[scale, np.ones(3), np.full(3, SHIFT_SCALE)]
        free = np.r_[free, np.ones(6, bool)]
    n_core = n_plant - (s if stiff else 0)

    def plant_of(x: Array) -> PlantParams:
        p = unpack(arm, x[:n_core], unit, base)
        return dataclasses.replace(p, segment_stiffness=tuple(map(float, x[n_core:n_plant]))) if stiff else p

    def full(xf: Array) -> Array:
        x = x0.copy()
        x[free] = xf
        return x

    def residual(xf: Array) -> Array:
        x = full(xf)
        tips = _corrected(x[n_plant:], sub.tips) if camera else sub.tips
        return (predicted_tips(arm, plant_of(x), sub) - tips).ravel()

    sol = least_squares(residual, x0[free], bounds=(lo[free], hi[free]), loss="soft_l1", f_scale=loss_scale,
                        x_scale=1.0, diff_step=1e-4)
    x = full(sol.x)
    plant = plant_of(x)
    r = residual(sol.x)
    J = np.asarray(sol.jac, float)
    n_res, n_par = r.size, sol.x.size
    sigma2 = float(r @ r) / max(1, n_res - n_par)
    cov = sigma2 * np.linalg.pinv(J.T @ J)
    se = np.full(x.size, np.nan)
    se[free] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    se *= scale
    notes = list(WITH_CAMERA_NOT_SEPARABLE if camera else ALWAYS_NOT_SEPARABLE)
    if stiff:  # the known load separates the stiffness from the arm's own load
        notes = [n for n in notes if not n.startswith("tip_force ~ segment_stiffness")]
    notes += _not_separated(J, cov, [n for n, f in zip(names, free) if f])
    lags = _lags(data)
    finite = [t for t in lags if math.isfinite(t)]
    if finite:
        plant = dataclasses.replace(plant, actuator_tau=float(np.median(finite)))
    values = {n: v for n, v, f in zip(names, (x * scale).tolist(), free) if f}
    values["actuator_tau"] = plant.actuator_tau
    std = {n: v for n, v, f in zip(names, se.tolist(), free) if f}
    if len(finite) > 1:
        std["actuator_tau"] = float(np.std(finite, ddof=1) / math.sqrt(len(finite)))
    return Identification(plant=plant, rms_m=float(np.sqrt(np.mean(r ** 2) * 3)), poses=int(ok.sum()),
                          values=values, std_errors=std, not_separable=notes, lag_per_actuator=lags,
                          world_correction=_correction(x[n_plant:]) if camera else None)


def _correction(c: Array) -> Array:
    """The rigid correction of {w} (4x4) of the fit's camera parameters (rotation vector [rad],
    shift in SHIFT_SCALE)."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.asarray(c[:3], float)).as_matrix()
    T[:3, 3] = np.asarray(c[3:6], float) * SHIFT_SCALE
    return T


def _corrected(c: Array, tips: Array) -> Array:
    """The tips [m] (N, 3) in {w} moved by the correction of the camera parameters ``c``."""
    T = _correction(c)
    return tips @ T[:3, :3].T + T[:3, 3]


def _camera_start(model: Array, tips: Array) -> Array:
    """The camera parameters of the closed-form rigid alignment of the measured ``tips`` onto the
    ``model``'s (Kabsch on the centred points, scipy's align_vectors)."""
    from scipy.spatial.transform import Rotation

    cm, ct = model.mean(axis=0), tips.mean(axis=0)
    rot, _ = Rotation.align_vectors(model - cm, tips - ct)
    shift = cm - rot.apply(ct)
    return np.r_[rot.as_rotvec(), shift / SHIFT_SCALE]


def _not_separated(J: Array, cov: Array, names: list[str]) -> list[str]:
    """The pairs of parameters whose estimates are correlated above CORRELATED, and the
    parameters of directions the data hardly determine (normalised singular value < WEAK)."""
    out = []
    d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    corr = cov / np.outer(d, d)
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if abs(corr[i, j]) > CORRELATED:
                out.append(f"{names[i]} ~ {names[j]} (correlation {corr[i, j]:+.3f} in this excitation)")
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    _, sv, Vt = np.linalg.svd(Jn, full_matrices=False)
    for k in np.flatnonzero(sv / max(sv[0], 1e-300) < WEAK).tolist():
        big = [names[i] for i in np.argsort(-np.abs(Vt[k]))[:2]]
        out.append(f"{' + '.join(big)}: undetermined by this excitation (singular value {sv[k] / sv[0]:.1e})")
    for i in np.flatnonzero(norms == 0).tolist():
        out.append(f"{names[i]}: not seen by this excitation")
    return out


def _lags(data: ExcitationData) -> list[float]:
    """Per actuator the motor's first-order lag [s] from the targets and encoders (NaN: none)."""
    sends = data.times[:-1] + 1e-9  # sent just after the cycle's reading
    return [fit_motor_lag(sends, data.targets[:-1, j], data.times, data.encoders[:, j])
            for j in range(data.encoders.shape[1])]
