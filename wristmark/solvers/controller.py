"""The controller interface and its configuration (the registry of kinds: solvers/controller_registry.py).

A controller turns the commanded configuration psi_cmd, the measured tip p_meas and the desired
tip p_des (+ its velocity v_des) into the next commanded configuration (paper eq. 21:
psi <- psi + psi_dot dt), always within the joint and velocity limits. An optional
:class:`OrientationTask` adds the tip frame's desired and measured orientation (the ``qp`` kind
only: the paper's controller is position-only as the paper defines it, and refuses one).
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_spec import Arm, ArmSpec, actuator_names, arm_size
from wristmark.models.config_io import flatten_sections, from_mapping, load_layered, sectioned, to_mapping
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import check_psi, tip_jacobian
from wristmark.models.limits import clamp_psi, clamp_velocity, psi_bounds
from wristmark.solvers.backlash_compensation import ActuatorCompensator, BacklashInverse, CommandCompensator
from wristmark.solvers.play_probe_fit import PlayFit

if TYPE_CHECKING:
    from wristmark.solvers.clearance import Capsules

Array = NDArray[np.float64]


BACKLASH_METHODS = ("schmitt", "encoders")
INTEGRAL_MODES = ("plain", "path")


@dataclass(frozen=True)
class ControllerConfig:
    """Controller settings (configs/controller.yaml, under 'controller:', in the sections of
    :data:`CONTROLLER_SECTIONS` or flat); SI units. The defaults are configs/controller.yaml's
    (tests/models/test_config_defaults.py): ``ControllerConfig()`` is the controller the command
    line runs.

    kind: "paper" (eq. 17-21) or "qp" (velocity-bounded QP). dt: servo cycle [s].
    paper: v_xlim constant tip speed [m/s]; gamma [m^2/s^2-free, eq. 20 damping]; xi threshold on
    the smallest singular value; saturate_near_target: use min(v_xlim, |dp|/dt) instead of the
    paper's constant speed; lock_saturated_joints: re-solve eq. 19-20 without a joint the step
    would push through its limit (not in the paper). qp: kp feedback gain [1/s]; max_correction_speed [m/s];
    feed_forward: add the desired velocity; feed_forward_undamped: the damping pulls psi_dot towards
    the least-motion rates that realise the desired velocity (QpController.feed_forward_rates)
    instead of zero, so that it shortens only the feedback, not the path's velocity (off in
    configs/controller.yaml: it moves the paper arm's numbers; docs/notes/any-arm-residual.md);
    damping: weight of ||S psi_dot||^2 relative to the
    tip-velocity error (S converts rad to tip metres, ``lever`` [m/rad]); orientation_weight:
    weight [m^2/rad^2] on keeping the tip frame's orientation (0 = position only); ki: integral
    gain on the tip error [1/s^2] (0 = none), its velocity capped at integral_speed_limit [m/s]
    (solvers/tip_integral.py); integral_mode: "plain" (ki sum(e dt)) or "path" (ki G v_des, the
    mismatch learnt as a linear map of the desired velocity: it turns with the path at a corner).
    clearance_m: the least surface distance [m] the qp keeps between its arm's body and the
    obstacles set by ``Controller.set_obstacles`` (other arms' capsules, solvers/clearance.py).
    Both kinds: backlash_compensation turns on the dead-band inversion
    of solvers/backlash_compensation.py: backlash_play_max [rad, m, m, m, m, m] (actuators phi,
    d, s1a, s1b, s2a, s2b) bounds the play it may assume, the estimate starts at backlash_start
    x that bound and (backlash_learning) is learnt at every reversal over backlash_window [s]
    either side at backlash_learning_rate per reversal; backlash_fraction of the estimate is
    inverted; backlash_hysteresis x the bound is how far the command must come back before its
    direction counts as reversed; backlash_lead [s] is a first-order lead on the inversion's
    offset (a reversal drives the lagging motor through the play in a one-cycle burst; 0 = none).
    backlash_method: "schmitt" (the direction from a Schmitt trigger on the command) or
    "encoders" (solvers/play_observer.py: the play's output tracked from the encoder readings
    the loop passes to ``step``; the side changes once the command leaves the band by
    backlash_margin x the bound; without readings nothing is inverted; once the desired path has
    stood still for backlash_freeze [s] the sides stay as they are until it moves (a held
    point's measurement noise does not send the motors across the band; 0 = never);
    backlash_release [s]: when the path moves again after such a freeze, what the feedback wound
    inside the bands meanwhile is let out with this time constant instead of by the first changes
    of side at once (the output's jump kicked the tip at a walk's first cycles; 0 = at once);
    backlash_buzz_time [s], backlash_buzz_turns, backlash_buzz_shrink: an actuator the feedback
    alone turns, its backlash_buzz_turns-th turn within backlash_buzz_time, buzzes across an
    overestimated play (a probe's under a loaded host): its play estimate is scaled by
    backlash_buzz_shrink, not under backlash_start x its bound (0 s = never);
    backlash_motor_burst: at a reversal of side the motor's target is sized from the encoders and
    the motor lag the play probe measured so that the motor reaches the new side's steady target
    in one cycle (instead of the lead's fixed burst; actuators without a measured lag keep the
    lead). backlash_kinds: the
    controller kinds the inversion applies to (configs/controller.yaml: qp only; the paper's
    constant-speed controller reverses the actuators every cycle and is not helped by it).
    backlash_actuator_space: an arm with more actuators than joints (tendons, antagonistic pairs),
    whose actuators cannot each be offset through a configuration, gets the inversion in actuator
    space (solvers/backlash_compensation.ActuatorCompensator: the offsets ride on the actuator
    targets, ``Controller.actuator_targets``); false: no inversion for such an arm.
    play_probe (the encoders' inversion only): before the first closed-loop walk the loop probes
    each actuator's play (rig/loop/play_probe.py: a triangle of play_probe_amplitude x its bound over
    play_probe_time [s] per actuator, then play_probe_settle [s] of closed-loop settle) and the
    inversion starts from the fitted play (solvers/play_probe_fit.py), learning it on from there
    (play_probe_learning) or keeping the probe's. play_probe_from_tip: an arm whose pose does not
    give its actuators (fewer than 6 joints, or more actuators than joints) is probed too, each
    actuator's output read from the tip's place and turn alone (rig/loop/play_probe.TipProjection);
    off by default:
    it helped in process (bench/any_arm.py) but not in the virtual lab at 0.35 x (noisier fits;
    docs/your-arm.md "Dead-band inversion per actuator").
    """

    kind: str = "qp"
    dt: float = 0.060
    v_xlim: float = 0.020
    gamma: float = 1e-6
    xi: float = 1e-3
    saturate_near_target: bool = False
    lock_saturated_joints: bool = True
    kp: float = 8.0
    max_correction_speed: float = 0.02
    feed_forward: bool = True
    feed_forward_undamped: bool = False
    damping: float = 1e-3
    lever: float = 0.2
    orientation_weight: float = 1e-3
    position_weight: float = 1.0
    pose_orientation_weight: float = 1e-3
    kr: float = 8.0  # [1/s], = kp: the same bandwidth as the position task
    max_angular_speed: float = 0.5  # [rad/s]
    qp_solver: str = "daqp"
    ki: float = 4.0
    integral_speed_limit: float = 0.003
    integral_mode: str = "path"
    clearance_m: float = 0.002
    backlash_compensation: bool = True
    backlash_play_max: tuple[float, ...] = (0.012, 0.0002, 0.00016, 0.00016, 0.00016, 0.00016)
    backlash_start: float = 0.15
    backlash_fraction: float = 0.75
    backlash_hysteresis: float = 0.1
    backlash_learning: bool = True
    backlash_window: float = 0.4
    backlash_learning_rate: float = 0.3
    backlash_lead: float = 0.03
    backlash_method: str = "encoders"
    backlash_margin: float = 0.01
    backlash_buzz_time: float = 1.0
    backlash_buzz_shrink: float = 0.7
    backlash_buzz_turns: int = 3
    backlash_freeze: float = 0.5
    backlash_release: float = 0.4
    backlash_motor_burst: bool = True
    backlash_kinds: tuple[str, ...] = ("qp",)
    backlash_actuator_space: bool = True
    play_probe: bool = True
    play_probe_amplitude: float = 2.0
    play_probe_time: float = 0.6
    play_probe_settle: float = 0.6
    play_probe_learning: bool = False
    play_probe_from_tip: bool = False

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for k in ("dt", "v_xlim", "gamma", "xi", "max_correction_speed", "damping", "lever", "position_weight",
                  "max_angular_speed"):
            if getattr(self, k) <= 0:
                raise ConfigError(f"'{k}' must be > 0, got {getattr(self, k)}")
        for k in ("kp", "orientation_weight", "pose_orientation_weight", "kr", "ki", "integral_speed_limit",
                  "clearance_m", "backlash_hysteresis", "backlash_window", "backlash_lead", "backlash_margin",
                  "backlash_freeze", "backlash_release", "backlash_buzz_time"):
            if getattr(self, k) < 0:
                raise ConfigError(f"'{k}' must be >= 0, got {getattr(self, k)}")
        if not self.backlash_play_max or min(self.backlash_play_max) < 0:
            raise ConfigError(f"'backlash_play_max' must be values >= 0 (one per actuator), "
                              f"got {list(self.backlash_play_max)}")
        for k in ("backlash_start", "backlash_fraction", "backlash_learning_rate", "backlash_buzz_shrink"):
            if not 0.0 <= getattr(self, k) <= 1.0:
                raise ConfigError(f"'{k}' must be in [0, 1], got {getattr(self, k)}")
        if not isinstance(self.backlash_buzz_turns, int) or self.backlash_buzz_turns < 1:
            raise ConfigError(f"'backlash_buzz_turns' must be an integer >= 1, got {self.backlash_buzz_turns!r}")
        if not set(self.backlash_kinds) <= set(CONTROLLER_KINDS):
            raise ConfigError(f"'backlash_kinds' must be among {', '.join(CONTROLLER_KINDS)}, "
                              f"got {list(self.backlash_kinds)}")
        if self.backlash_method not in BACKLASH_METHODS:
            raise ConfigError(f"'backlash_method' must be one of {', '.join(BACKLASH_METHODS)}, "
                              f"got {self.backlash_method!r}")
        if self.backlash_motor_burst and self.backlash_method != "encoders":
            raise ConfigError("'backlash_motor_burst' needs backlash_method: encoders (the motors' lags come from "
                              "the play probe's encoder readings)")
        if self.play_probe_amplitude < 1.0:
            raise ConfigError(f"'play_probe_amplitude' must be >= 1 (x backlash_play_max), "
                              f"got {self.play_probe_amplitude}")
        if self.play_probe_time <= 0.0 or self.play_probe_settle < 0.0:
            raise ConfigError(f"'play_probe_time' must be > 0 and 'play_probe_settle' >= 0 [s], got "
                              f"{self.play_probe_time} and {self.play_probe_settle}")
        if self.integral_mode not in INTEGRAL_MODES:
            raise ConfigError(f"'integral_mode' must be one of {', '.join(INTEGRAL_MODES)}, got {self.integral_mode!r}")
        if self.qp_solver not in ("daqp", "qpoases"):
            raise ConfigError(f"'qp_solver' must be daqp or qpoases, got {self.qp_solver!r}")

    def play_max_for(self, arm: Arm) -> Array:
        """``backlash_play_max`` for ``arm``'s actuators: one entry per actuator as given; the
        reference arm's six entries [phi, d, s1a, s1b, s2a, s2b] given for another arm are sized
        to it by kind (revolute stem joints and direct actuators: phi's, prismatic: d's, pull
        actuators: the largest backbone entry); any other length is refused (ConfigError naming
        the key, the expected length and the actuators)."""
        m = arm_size(arm)[1]
        given = np.asarray(self.backlash_play_max, float)
        if given.size == m:
            return given
        if given.size == 6 and isinstance(arm, ArmSpec):
            out = [given[0] if j.joint == "revolute_z" else given[1] for j in arm.stem]
            for s in arm.segments:
                out += [given[0] if s.actuation.type == "direct" else float(given[2:].max())] * s.actuators
            return np.array(out)
        raise ConfigError(f"'backlash_play_max' must have {m} entries (one per actuator: "
                          f"{', '.join(actuator_names(arm))}), got {given.size}")

    @classmethod
    def load(cls, path: str | Path) -> ControllerConfig:
        """Load from YAML (a 'controller:' mapping, or the mapping itself; ``extends`` resolved:
        docs/configuration.md); a key no file of the chain states takes the dataclass default
        (configs/controller.yaml's)."""
        return from_mapping(cls, load_layered(path, "controller", flat_controller_mapping), str(path))

    def sections(self) -> dict[str, Any]:
        """The settings as controller.yaml lays them out: kind and dt, then one mapping per
        section of :data:`CONTROLLER_SECTIONS`."""
        return sectioned(to_mapping(self), CONTROLLER_LAYOUT, {k: v[0] for k, v in CONTROLLER_SECTIONS.items()})


# controller.yaml's sections by concern: name -> (what it holds, its keys); kind and dt stay at the
# top. A flat file (every key under 'controller:', the format before the sections) means the same.
CONTROLLER_SECTIONS: dict[str, tuple[str, tuple[str, ...]]] = {
    "paper": ("the paper's controller, eq. 17-21",
              ("v_xlim", "gamma", "xi", "saturate_near_target", "lock_saturated_joints")),
    "qp": ("the velocity-bounded QP, its pose task and its tip-error integral",
           ("kp", "max_correction_speed", "feed_forward", "feed_forward_undamped", "damping", "lever",
            "orientation_weight", "position_weight",
            "pose_orientation_weight", "kr", "max_angular_speed", "qp_solver", "ki", "integral_speed_limit",
            "integral_mode", "clearance_m")),
    "backlash": ("the dead-band inversion, either kind",
                 ("backlash_compensation", "backlash_play_max", "backlash_start", "backlash_fraction",
                  "backlash_hysteresis", "backlash_learning", "backlash_window", "backlash_learning_rate",
                  "backlash_lead", "backlash_method", "backlash_margin", "backlash_freeze", "backlash_release",
                  "backlash_motor_burst",
                  "backlash_buzz_time", "backlash_buzz_shrink", "backlash_buzz_turns",
                  "backlash_kinds", "backlash_actuator_space")),
    "probe": ("the play probe before the first closed-loop walk",
              ("play_probe", "play_probe_amplitude", "play_probe_time", "play_probe_settle", "play_probe_learning",
               "play_probe_from_tip")),
}
CONTROLLER_LAYOUT: dict[str, str] = {k: name for name, (_, keys) in CONTROLLER_SECTIONS.items() for k in keys}


def flat_controller_mapping(data: dict[str, Any], source: str) -> dict[str, Any]:
    """One controller file's mapping, flat: the keys of its sections (each in its own) next to
    kind and dt, or the flat mapping as it is (config_io.flatten_sections)."""
    return flatten_sections(data, source, CONTROLLER_LAYOUT, {k: v[0] for k, v in CONTROLLER_SECTIONS.items()})


@dataclass(frozen=True)
class OrientationTask:
    """The tip frame's orientation for one step, in {w}: desired rotation R_des (3x3) and angular
    velocity w_des [rad/s]; the measured rotation R_meas (3x3); axis_only: only the measured z
    axis is trusted (the reference sleeve, or a coded one whose code was not read): the task then
    steers the axis direction (2 DoF) and leaves the roll about it free."""

    R_des: Array
    w_des: Array
    R_meas: Array
    axis_only: bool = False

    @classmethod
    def of(cls, R_des: Array | None, w_des: Array | None, R_meas: Array | None,
           roll_known: bool) -> OrientationTask | None:
        """The task, or None when no orientation is asked for or none was measured (the step is
        then position only); axis only unless the measurement's roll is known."""
        if R_des is None or w_des is None or R_meas is None:
            return None
        return cls(R_des, w_des, R_meas, axis_only=not roll_known)


@dataclass(frozen=True)
class ControlStep:
    """One controller step: next psi (in limits), psi_dot (in limits), commanded tip velocity."""

    psi_next: Array
    psi_dot: Array
    v_tip_cmd: Array
    status: str
    solve_time_us: float


class Controller(abc.ABC):
    """Base of every controller kind: each step maps psi [rad, m, ...], the desired tip and its
    velocity in {w} [m, m/s] and the measured tip in {w} [m] to the next psi within the limits.
    ``supports_orientation``: the kind also takes an OrientationTask (rotations in {w})."""

    supports_orientation = False
    supports_obstacles = False

    def __init__(self, params: Arm, config: ControllerConfig) -> None:
        self.params = params
        self.config = config
        self.n = arm_size(params)[0]
        self.compensator: CommandCompensator | None = None
        # per actuator: the largest play assumed (ConfigError when the config's list does not fit the arm)
        self.play_max = config.play_max_for(params) if config.backlash_compensation else np.zeros(arm_size(params)[1])
        n, m = arm_size(params)
        # the inversion offsets each actuator on its own: an arm with more actuators than joints
        # (tendons, antagonistic pairs) has no configuration for an offset of one actuator alone,
        # so its offsets go to the actuators beside the configuration (ActuatorCompensator), or,
        # with backlash_actuator_space off, nowhere
        on = config.backlash_compensation and config.kind in config.backlash_kinds
        self.compensation_note = "" if m == n or not on else (
            f"dead-band inversion in actuator space: the arm's {m} actuators drive {n} joints (tendons or pairs), "
            "so the offsets are added to the actuator targets" if config.backlash_actuator_space else
            f"dead-band inversion off: the arm's {m} actuators drive {n} joints (tendons or pairs) and "
            "backlash_actuator_space is off; the feedback covers the play")
        if on and m == n:
            self.compensator = CommandCompensator(params, make_inverse(config, self.play_max))
        elif on and config.backlash_actuator_space:
            self.compensator = ActuatorCompensator(params, make_inverse(config, self.play_max))
        # the servo loop passes the encoder readings to step() when this is true
        self.uses_encoders = self.compensator is not None and config.backlash_method == "encoders"
        self.play_probed = False  # a play probe (rig/loop/play_probe.py) has run, or was skipped

    @property
    def play_shrinks(self) -> int:
        """How often the encoders' dead-band inversion shrank a play the feedback buzzed across
        (solvers/play_observer.py, ``backlash_buzz_time``; 0 without that inversion)."""
        inverse = getattr(self.compensator, "inverse", None)
        return int(getattr(inverse, "buzzes", 0))

    def hand_over_compensation(self, note: str) -> None:
        """Leave the dead-band inversion to the link (``--model``: rig/link/model_link.py inverts
        the identified plays and lag): no compensator, no encoders, no play probe; ``note`` says so."""
        self.compensator = None
        self.uses_encoders = False
        self.compensation_note = note

    @property
    def wants_play_probe(self) -> bool:
        """True until the loop has run the play probe this controller is configured for."""
        return self.uses_encoders and self.config.play_probe and not self.play_probed

    def start_play(self, fits: Sequence[PlayFit] | None, encoders: Array | None = None,
                   psi_nominal: Array | None = None) -> Array | None:
        """Start the inversion from a play probe's fits (None: the probe was skipped; the play is
        then learnt online), the encoders read now [rad, m, ...] and the nominal configuration
        to hold (the arm as it was before the probe); returns the configuration to send for it
        (within the limits; None when there is nothing to start)."""
        self.play_probed = True
        comp = self.compensator
        if comp is None or fits is None or encoders is None or psi_nominal is None:
            return None
        from wristmark.solvers.play_observer import PlayObserverInverse

        if not isinstance(comp.inverse, PlayObserverInverse):
            return None
        comp.inverse.seed(np.array([f.play for f in fits]), np.array([f.last_output for f in fits]),
                          np.array([f.ok for f in fits]), relearn=self.config.play_probe_learning,
                          motor_tau=np.array([f.motor_tau for f in fits]))
        comp.inverse.observe(np.asarray(encoders, float))
        nominal = clamp_psi(self.params, check_psi(psi_nominal, self.params))
        out = clamp_psi(self.params, comp.compensate(nominal, self.config.dt))
        comp.commit(nominal, out)
        return out

    def note_start_move(self, encoders_before: Array, encoders_after: Array) -> None:
        """The loop's start ramp moved the motors from ``encoders_before`` to ``encoders_after``
        [rad, m, ...] (encoder readings): the encoders' dead-band inversion learns the first
        reversals of the actuators it moved at its normal rate (PlayObserverInverse.after_move)."""
        from wristmark.solvers.play_observer import PlayObserverInverse

        comp = self.compensator
        if comp is not None and isinstance(comp.inverse, PlayObserverInverse):
            comp.inverse.after_move(encoders_before, encoders_after)

    def actuator_targets(self, psi_cmd: Array) -> Array:
        """The actuator targets [rad, m, ...] to send for the command ``psi_cmd``: its actuator
        coordinates (models.actuation), plus the dead-band inversion's per-actuator offsets when they
        live in actuator space (an arm with more actuators than joints: ActuatorCompensator)."""
        if self.compensator is None:
            return actuators_from_psi(self.params, psi_cmd)
        return self.compensator.actuators(psi_cmd)

    def output_model(self, psi_cmd: Array) -> Array:
        """The configuration [rad, m, ...] the arm is expected to reach for the command ``psi_cmd``:
        with the dead-band inversion, the nominal configuration behind the last command returned
        (its offsets move the motors across the band, not the arm); else ``psi_cmd``. No state
        changes."""
        if self.compensator is None:
            return np.asarray(psi_cmd, float).copy()
        return self.compensator.nominal_of(psi_cmd)

    def set_obstacles(self, caps: Capsules | None, clearance_m: float | None = None, xi: float = 0.5) -> None:
        """Keep the arm's body ``clearance_m`` [m] (None: the config's ``clearance_m``) from the
        capsules ``caps`` (other arms' bodies, in this arm's {w}: solvers/clearance.py) in the next
        steps, closing at most the share ``xi`` of the gap above it per step; None clears them.
        Only a kind with a constraint slot (``supports_obstacles``: the qp) takes them: the
        paper's eq. 17-21 has none, and refuses (ConfigError); None is accepted by every kind."""
        if caps is not None:
            raise ConfigError(f"the {self.config.kind!r} controller has no constraint slot for a clearance "
                              "between arms; it needs the qp controller")

    def reset(self) -> None:
        """Forget the internal state (integral, backlash directions) before a new run."""
        if self.compensator is not None:
            self.compensator.reset()

    def path_rates(self, psi: Array, v_tip: Array) -> Array:
        """Joint rates [rad/s, m/s] for a tip velocity ``v_tip`` [m/s] in {w} with no error and no
        limits (default: eq. 19, the 6x6 Jacobian's pseudo-inverse with zero angular rate); also
        maps a tip displacement [m] to joint displacements."""
        from wristmark.solvers.pseudo_inverse import sr_pseudo_inverse

        J = tip_jacobian(self.params, psi)
        if self.n < 6:  # fewer joints than a pose: the position rows alone
            return sr_pseudo_inverse(J[:3], self.config.gamma, self.config.xi) @ v_tip
        return sr_pseudo_inverse(J, self.config.gamma, self.config.xi) @ np.concatenate([v_tip, np.zeros(3)])

    @abc.abstractmethod
    def velocity(self, psi: Array, p_meas: Array, p_des: Array, v_des: Array | None,
                 dt: float, orientation: OrientationTask | None = None) -> tuple[Array, Array, str]:
        """psi_dot [rad/s, m/s], commanded tip velocity [m/s] and a status word."""

    def step(self, psi_cmd: Array, p_meas_world: Array, p_des_world: Array,
             v_des_world: Array | None, dt: float, orientation: OrientationTask | None = None,
             encoders: Array | None = None) -> ControlStep:
        """Next commanded configuration from the measured and desired tip in {w} [m] (and, for
        a kind that supports it, the tip frame's orientation; ConfigError from one that does not).
        ``encoders``: the motor encoder readings [rad, m, m, m, m, m] taken with the measurement
        (optional; used by the ``encoders`` dead-band inversion only).

        With backlash compensation the controller works on the nominal configuration behind
        ``psi_cmd`` and returns the compensated one; the returned step is within the joint and
        velocity limits either way."""
        import time

        if orientation is not None and not self.supports_orientation:
            raise ConfigError(f"the {self.config.kind!r} controller is position-only; orientation control "
                              f"needs the qp controller")
        if orientation is not None and self.n < 6:
            raise ConfigError(f"the arm has {self.n} joints: it cannot hold a tip orientation as well as a position "
                              f"(orientation control needs 6 or more)")
        psi_in = clamp_psi(self.params, check_psi(psi_cmd, self.params))
        comp = self.compensator
        psi = psi_in if comp is None else comp.nominal(psi_in)
        if comp is not None and encoders is not None:
            comp.inverse.observe(np.asarray(encoders, float))
        t0 = time.perf_counter()
        psi_dot, v_tip, status = self.velocity(psi, np.asarray(p_meas_world, float),
                                               np.asarray(p_des_world, float),
                                               None if v_des_world is None else np.asarray(v_des_world, float), dt,
                                               orientation)
        us = 1e6 * (time.perf_counter() - t0)
        psi_dot = clamp_velocity(self.params, np.nan_to_num(psi_dot))
        lo, hi = psi_bounds(self.params)
        nxt = np.clip(psi + psi_dot * dt, lo, hi)
        if comp is not None:
            nominal = nxt
            path = None if v_des_world is None else self.path_rates(psi, np.asarray(v_des_world, float))
            out_dot = clamp_velocity(self.params, (comp.compensate(nominal, dt, path) - psi_in) / dt)
            nxt = clamp_psi(self.params, np.clip(psi_in + out_dot * dt, lo, hi))
            comp.commit(nominal, nxt)
        psi_dot = (nxt - psi_in) / dt
        return ControlStep(clamp_psi(self.params, nxt), psi_dot, v_tip, status, us)


CONTROLLER_KINDS = ("paper", "qp")


def make_inverse(config: ControllerConfig, play_max: Array | None = None) -> BacklashInverse:
    """The dead-band inversion ``config.backlash_method`` with the config's settings (``play_max``
    per actuator: the arm's, :meth:`ControllerConfig.play_max_for`; None: the config's list)."""
    common = dict(start=config.backlash_start, fraction=config.backlash_fraction, learn=config.backlash_learning,
                  window=config.backlash_window, rate=config.backlash_learning_rate, lead=config.backlash_lead)
    play_max = np.asarray(config.backlash_play_max if play_max is None else play_max, float)
    if config.backlash_method == "encoders":
        from wristmark.solvers.play_observer import PlayObserverInverse

        return PlayObserverInverse(play_max, config.backlash_margin, freeze=config.backlash_freeze,
                                   release=config.backlash_release,
                                   motor_burst=config.backlash_motor_burst, buzz_time=config.backlash_buzz_time,
                                   buzz_shrink=config.backlash_buzz_shrink, buzz_turns=config.backlash_buzz_turns,
                                   **common)  # type: ignore[arg-type]
    return BacklashInverse(play_max, config.backlash_hysteresis, **common)  # type: ignore[arg-type]
