"""Dead-band (backlash) inversion on the commanded actuators, with the play learnt online.

Assumed plant (sim/plant.py, and the usual model of a cable / lead-screw transmission): per
actuator j a play operator of width b_j sits between the motor and the arm, so after the motor
reverses it travels b_j before the arm moves again. The inversion adds +-fraction * b_hat_j / 2
to the nominal actuator command in the direction the command travels, so the motor crosses the
play when the command reverses instead of the feedback winding it through over several cycles
(which, with the loop's delay, makes the tip swing about the path after each corner).

What it needs is only what the controller sees: its own commanded configuration (the
nominal command, driven by the vision's tip through the feedback) and the desired path's
velocity (to tell the feedback's share of the command from the path's); it ignores the encoder
readings (solvers/play_observer.py, configs/controller_encoders.yaml, tracks the play's output
from them and shares this class's learning and lead). Assumptions: the play is constant per
actuator and below ``play_max``; the desired path reverses an actuator at most every couple of
windows; the arm's gain errors are alike on both sides of a reversal (the estimator's drift
cancellation).

The direction must not follow noise (measurement noise makes the command jitter by a few
micrometres): it flips only once the command has come back more than hysteresis * play_max
from its extreme value since the last flip (a Schmitt trigger).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuator_jacobian, actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm
from wristmark.models.limits import actuator_bounds, delta_indices, wrap_angle

Array = NDArray[np.float64]


class BacklashInverse:
    """Per-actuator dead-band inversion with a Schmitt trigger and an online play estimate.

    The direction of actuator j flips once the nominal command has come back more than
    ``hysteresis`` * play_max_j from its extreme value since the last flip. The offset is
    ``fraction`` * b_hat_j / 2 in that direction (the loop's feedback is fast enough to cover
    part of the play itself; a full inversion then overshoots).

    Learning (``learn``): the feedback part of the command F_j (the nominal command minus the
    desired path's actuator motion, integrated) has to supply whatever play is left
    uncompensated. Over ``window`` seconds either side of a reversal, the change of F_j in the
    new direction is that residual, so b_est = residual + the offset jump applied; b_hat moves
    towards it by ``rate`` per reversal, within [0, play_max]. Known bias: F_j also holds the
    loop's lag behind the path (output behind command by the path rate x the loop's delay),
    which turns round with the motion, so b_est = b + 2 |rate| x delay: the estimate errs high,
    most on an arm with little play (docs/notes/dead-band-inversion.md).

    Lead (``lead`` [s], 0 = none): the motor follows its target through a first-order lag, so a
    step of the offset by b at a reversal takes the lag's time constant to cross the play while
    the arm stands still and the error grows. The offset sent is off + lead * d(off)/dt, i.e. on
    the flip cycle the jump is (1 + lead / dt) times the steady one and the motor crosses the
    play within about one cycle; the next cycle it settles on the steady offset. Assumes the
    motor lag is of the order of lead (arms with a much faster motor see the burst as a short
    push past the play)."""

    def __init__(self, play_max: Array, hysteresis: float, start: float = 0.5, fraction: float = 0.5,
                 learn: bool = True, window: float = 0.4, rate: float = 0.3, lead: float = 0.0) -> None:
        self.play_max = np.asarray(play_max, float)
        self.lead = float(lead)
        self._burst_gain = 1.0  # largest offset / the steady one (the lead's burst at a flip)
        self.hysteresis = float(hysteresis)
        self.start, self.fraction, self.learn = float(start), float(fraction), bool(learn)
        self.window, self.rate = float(window), float(rate)
        # True: the first reversals are averaged (step 1 / (n + 1), at least ``rate``), then ``rate``
        self.average_first = False
        self.burst_first = True  # the lead's burst also when a direction is first taken
        self.reset()

    @property
    def half(self) -> Array:
        """Half the largest offset the inversion applies per actuator [rad, m, ...]."""
        return 0.5 * self.fraction * self.play_max * self._burst_gain

    def reset(self, keep_estimate: bool = False) -> None:
        """Forget the direction (no compensation until the command moves) and, unless
        ``keep_estimate``, the learnt play."""
        if not keep_estimate or not hasattr(self, "play"):
            self.play = self.start * self.play_max
            self._learnt = np.zeros(self.play_max.size)  # reversals learnt from, per actuator
        self.direction = np.zeros(self.play_max.size)
        self.extreme: Array | None = None
        self.time = 0.0
        self._fb = np.zeros(self.play_max.size)
        self._off = np.zeros(self.play_max.size)
        self._history: list[tuple[float, Array]] = []
        self._open: list[tuple[int, float, float, float, float]] = []  # j, due, F before, dir, jump

    def offset(self, a_nom: Array, dt: float, a_dot_path: Array | None = None) -> Array:
        """Offset [rad, m, ...] to add to the nominal actuator command ``a_nom`` after a cycle of
        ``dt`` [s]; learning uses ``a_dot_path``, the desired path's actuator rates [rad/s, m/s, ...]."""
        a = np.asarray(a_nom, float)
        self.time += dt
        self._track_feedback(a, dt, a_dot_path)
        d = self.direction
        flip, new = self._turn(a)
        if self.learn:
            self._learn(flip, d, new)
        self.direction = new
        off = self.direction * 0.5 * self.fraction * self.play
        if not self.burst_first:  # a first direction is no reversal: no burst
            self._off = np.where(d == 0.0, off, self._off)
        # first-order lead on the offset: a flip drives the motor through the play in one burst
        self._burst_gain = 1.0 + 2.0 * self.lead / dt if dt > 0.0 else 1.0
        burst = off + self.lead / dt * (off - self._off) if self.lead > 0.0 and dt > 0.0 else off
        self._off = off
        return np.asarray(burst, float)

    def observe(self, motor: Array) -> None:
        """Encoder readings [rad, m, ...]: not used by the Schmitt trigger (see play_observer.py)."""

    def _track_feedback(self, a: Array, dt: float, a_dot_path: Array | None) -> None:
        """Integrate the feedback's share of the command (the command minus the path's motion)."""
        if self.extreme is None:
            self.extreme = a.copy()
            self._last = a.copy()
        path = np.zeros(a.size) if a_dot_path is None else np.asarray(a_dot_path, float) * dt
        self._fb = self._fb + (a - self._last) - path
        self._last = a.copy()
        self._history.append((self.time, self._fb.copy()))
        while self._history and self._history[0][0] < self.time - self.window - 1e-9:
            self._history.pop(0)

    def _turn(self, a: Array) -> tuple[NDArray[np.bool_], Array]:
        """Which actuators reverse this cycle and the new directions (the Schmitt trigger)."""
        assert self.extreme is not None
        moved = a - self.extreme
        d = self.direction
        onward = (d != 0.0) & (d * moved >= 0.0)
        self.extreme = np.where(onward, a, self.extreme)
        flip = ~onward & (np.abs(moved) > self.hysteresis * self.play_max)
        self.extreme = np.where(flip, a, self.extreme)
        return flip, np.where(flip, np.sign(moved), d)

    def _learn(self, flip: NDArray[np.bool_], old: Array, new: Array) -> None:
        keep = []
        for j, due, before, dirn, jump in self._open:
            if flip[j]:
                continue  # turned again before the verdict: no clean reversal to learn from
            if self.time + 1e-9 >= due:
                est = dirn * (self._fb[j] - before) + jump
                rate = max(self.rate, 1.0 / (1.0 + self._learnt[j])) if self.average_first else self.rate
                self._learnt[j] += 1
                self.play[j] = float(np.clip((1 - rate) * self.play[j] + rate * est, 0.0, self.play_max[j]))
            else:
                keep.append((j, due, before, dirn, jump))
        before_fb = self._history[0][1]
        for k in np.flatnonzero(flip & (old != 0.0)):
            keep.append((int(k), self.time + self.window, float(before_fb[k]), float(new[k]),
                         self.fraction * float(self.play[k])))
        self._open = keep


class CommandCompensator:
    """Keeps the nominal command apart from the compensated one sent to the arm.

    The servo loop hands the controller back the configuration it last returned (the
    compensated one); ``nominal`` recovers the nominal configuration from it, ``compensate``
    turns the controller's next nominal configuration into the one to send. A configuration
    that is not the last one returned (a new phase, a held arm restarted elsewhere) resets it."""

    def __init__(self, params: Arm, inverse: BacklashInverse) -> None:
        self.params = params
        self.inverse = inverse
        self._offset = np.zeros(inverse.play_max.size)
        self._deltas = delta_indices(params)
        self._last_out: Array | None = None

    def reset(self, keep_estimate: bool = False) -> None:
        """Forget the offset, the directions and (unless ``keep_estimate``) the learnt play."""
        self._offset = np.zeros(self.inverse.play_max.size)
        self._last_out = None
        self.inverse.reset(keep_estimate)

    def nominal(self, psi_cmd: Array) -> Array:
        """Nominal configuration behind the commanded one ``psi_cmd``."""
        if self._last_out is None or not np.allclose(psi_cmd, self._last_out, rtol=0.0, atol=1e-12):
            self.reset(keep_estimate=True)
        return self.nominal_of(psi_cmd)

    def nominal_of(self, psi_cmd: Array) -> Array:
        """The nominal configuration behind ``psi_cmd`` when it is the last one returned, else
        ``psi_cmd`` itself; unlike :meth:`nominal`, never changes the state."""
        if self._last_out is None or not np.allclose(psi_cmd, self._last_out, rtol=0.0, atol=1e-12):
            return np.asarray(psi_cmd, float).copy()
        return self._to_psi(actuators_from_psi(self.params, psi_cmd) - self._offset, psi_cmd)

    def compensate(self, psi_nom: Array, dt: float, psi_dot_path: Array | None = None) -> Array:
        """The configuration to command for the nominal ``psi_nom`` after a cycle of ``dt`` [s]
        (before any limits); ``psi_dot_path`` the joint rates the desired path alone asks for."""
        a_nom = actuators_from_psi(self.params, psi_nom)
        a_dot = None if psi_dot_path is None else actuator_jacobian(self.params, psi_nom) @ psi_dot_path
        return self._to_psi(a_nom + self.inverse.offset(a_nom, dt, a_dot), psi_nom)

    def commit(self, psi_nom: Array, psi_out: Array) -> None:
        """Record what was finally sent (after the limits) for the nominal ``psi_nom``."""
        off = actuators_from_psi(self.params, psi_out) - actuators_from_psi(self.params, psi_nom)
        self._offset = np.clip(off, -self.inverse.half, self.inverse.half)
        self._last_out = np.asarray(psi_out, float).copy()

    def actuators(self, psi_cmd: Array) -> Array:
        """The actuator targets [rad, m, ...] to send for the commanded configuration ``psi_cmd``:
        its actuator coordinates (the offsets are already in it)."""
        return actuators_from_psi(self.params, psi_cmd)

    def _to_psi(self, a: Array, near: Array) -> Array:
        q = psi_from_actuators(self.params, a, delta_hint=near)
        for i in self._deltas:  # the bending-plane angle nearest the reference (no 2 pi jumps)
            q[i] = near[i] + wrap_angle(float(q[i] - near[i]))
        return q


class ActuatorCompensator(CommandCompensator):
    """The dead-band inversion in actuator space, for an arm with more actuators than joints
    (tendons, antagonistic pairs: m > n), where an offset of one actuator alone has no
    configuration: the controller's configuration stays the nominal one, and the offsets live
    beside it, per actuator. The loop sends ``actuators(psi_cmd)`` = the nominal actuator
    coordinates (models.actuation, the arm's map) + the offsets, instead of the map of a
    configuration: each actuator's motor crosses its own play. What the arm does with the
    offsets is its least-squares inverse map's business (the simulated true arm reads its
    outputs back so, models/arm_actuation.py): on a side the play takes the offset back out.

    Same interface as :class:`CommandCompensator`; ``nominal`` and ``compensate`` return the
    nominal configuration itself (the offsets move the motors across the bands, not the arm)."""

    def __init__(self, params: Arm, inverse: BacklashInverse) -> None:
        super().__init__(params, inverse)
        self._pending = np.zeros(inverse.play_max.size)  # the offsets computed, not yet committed

    def nominal_of(self, psi_cmd: Array) -> Array:
        """The nominal configuration behind ``psi_cmd``: ``psi_cmd`` itself (the offsets are not in it)."""
        return np.asarray(psi_cmd, float).copy()

    def compensate(self, psi_nom: Array, dt: float, psi_dot_path: Array | None = None) -> Array:
        """The nominal ``psi_nom`` itself; the offsets for its actuators are computed and kept
        for :meth:`actuators` (``psi_dot_path``: the joint rates the desired path alone asks for)."""
        a_nom = actuators_from_psi(self.params, psi_nom)
        a_dot = None if psi_dot_path is None else actuator_jacobian(self.params, psi_nom) @ psi_dot_path
        self._pending = np.asarray(self.inverse.offset(a_nom, dt, a_dot), float)
        return np.asarray(psi_nom, float).copy()

    def commit(self, psi_nom: Array, psi_out: Array) -> None:
        """Record what was finally commanded (after the limits): its offsets are the last ones
        computed (:meth:`compensate`; none when it has not run)."""
        self._offset = np.clip(self._pending, -self.inverse.half, self.inverse.half)
        self._pending = np.zeros_like(self._offset)
        self._last_out = np.asarray(psi_out, float).copy()

    def actuators(self, psi_cmd: Array) -> Array:
        """The actuator targets [rad, m, ...] for ``psi_cmd``: its actuator coordinates plus the
        offsets when it is the configuration last returned (within the actuators' bounds,
        models.limits.actuator_bounds, which a box enforces), else its coordinates alone."""
        a = actuators_from_psi(self.params, psi_cmd)
        if self._last_out is None or not np.allclose(psi_cmd, self._last_out, rtol=0.0, atol=1e-12):
            return a
        lo, hi = actuator_bounds(self.params)
        return np.asarray(np.clip(a + self._offset, lo, hi), float)
