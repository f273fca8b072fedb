"""Dead-band inversion with state: the play's output tracked from the motor encoders.

Assumed plant (sim/plant.py, the usual model of a cable / lead-screw transmission): per actuator
j a motor (what the encoders read) drives the arm through a play operator of width b_j, so the
output y_j stays put while the motor m_j moves inside [y_j - b_j / 2, y_j + b_j / 2] and is
dragged along at either edge. With an estimate b_hat the output is tracked by the same operator
on the encoder readings (sampled once a cycle, when the frame is taken):

    y_hat = clip(y_hat, m - b_hat / 2, m + b_hat / 2)

and the classical backlash inverse commands the motor to u + side * b_hat / 2, where u is the
nominal actuator command (what the output should reach) and side is the edge of the band the
motor must push on: +1 once u is above y_hat by more than ``margin`` x play_max, -1 once below by
as much, unchanged in between. So the motor jumps across the band when the *desired output*
leaves it, not when the noisy command turns round: no Schmitt trigger on the command. A side
decided a cycle early or late (e.g. by a 1 um rounding of a target) moves the motor inside the
band, which does not move the arm; the encoder readings are rounded to micro-units (1 um,
1 urad, the wire's resolution) before use, so a reading through the serial link and one taken
in process give the same decisions.

Only ``fraction`` of b_hat is inverted (the loop's feedback covers the rest and an inversion larger
than the play pushes the arm about at every change of side). The play estimate and its learning
are those of :class:`BacklashInverse` (the feedback's share of the command over ``window`` either
side of a change of side; it errs high by 2 x path rate x the loop's delay), as is the optional
lead on the offset, with two differences: the first reversals of each actuator are averaged
(step 1 / (n + 1), then ``rate``), so the estimate leaves its low start after one reversal, and
taking a first side (after a reset) gets no lead burst (it is no reversal). The output's initial
position in the band is unknown: the first reading puts it at the middle, unless a play probe
(rig/loop/play_probe.py) seeded it (:meth:`PlayObserverInverse.seed`: the fitted play, the output's
place in the band and so its side; the learning then goes on at ``rate`` from the fitted play).
Without encoder readings (a controller stepped without them) it inverts nothing: the plain controller.

Held point (``freeze`` [s], 0 = off): once the desired path has stood still that long (its
actuator rates exactly zero: a point hold, or a settle), the sides no longer change until it moves
again. At a held point the nominal command moves only by the measurement noise, and every change
of side would send the motor across the band without moving the arm (docs/notes/play-probe.md: the
commanded and measured stem then differ by up to 7.8 mrad at the virtual lab's held point).

Reversal burst from the motor's lag (``motor_burst``, ``backlash_motor_burst``): the lead's burst
is a fixed multiple of the offset's jump, right for a motor of ~the lead's lag; a slower motor
crosses the band over two or three cycles while the arm stands (docs/notes/motor-lag-burst.md:
 the 75 ms motors of an unseen arm at a corner where both first backbones reverse).
With the motors' first-order lags tau measured by the play probe from the encoders
(:meth:`seed`), the flip cycle of an actuator whose motor has not reached the new side's edge
sends instead the target that brings the motor from its reading to the steady target in one
cycle, m + (goal - m) / (1 - exp(-dt / tau)), within the lead's largest offset. Assumed: first-order
motors, their lags constant after the probe; without a probed lag the lead's burst stays.

Also assumed: the encoders read the motor (before the play) when the frame is taken; the play is
constant per actuator and below ``play_max``; the feedback-share learning's assumptions (see
:class:`BacklashInverse`). Measured limits (docs/notes/dead-band-inversion.md): the insertion's play is
learnt poorly (its path rate is the tip's speed, so the learning's bias is large) and is often
clipped at its bound.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.units import on_micro_grid
from wristmark.solvers.backlash_compensation import BacklashInverse

Array = NDArray[np.float64]


class PlayObserverInverse(BacklashInverse):
    """Per-actuator dead-band inversion driven by the play output observed from the encoders.

    ``margin`` x play_max_j [rad, m, ...] is how far the nominal command must leave the observed
    output before the side changes; the other arguments are :class:`BacklashInverse`'s (its
    ``hysteresis`` is not used)."""

    def __init__(self, play_max: Array, margin: float, start: float = 0.5, fraction: float = 0.5,
                 learn: bool = True, window: float = 0.4, rate: float = 0.3, lead: float = 0.0,
                 freeze: float = 0.0, motor_burst: bool = False, buzz_time: float = 0.0,
                 buzz_shrink: float = 1.0, buzz_turns: int = 3, release: float = 0.0) -> None:
        self.margin = float(margin)
        # the path moves again after a freeze: what the feedback wound inside the bands meanwhile
        # is let out over this time constant [s] (0: at once, by the first changes of side)
        self.release = float(release)
        # an actuator turned by the feedback alone (its path does not move it to the new side) and
        # for the ``buzz_turns``-th time within ``buzz_time`` [s] buzzes across an overestimated
        # play: each turn moves the motor by the inverted play, the tip over, the feedback back. Its
        # play estimate (a probe's too) is then scaled by ``buzz_shrink``, not under ``start`` x
        # play_max (the learning's own start; buzz_time 0: never)
        self.buzz_time, self.buzz_shrink, self.buzz_turns = float(buzz_time), float(buzz_shrink), int(buzz_turns)
        self.buzzes = 0  # turns that shrank a play
        self._path_rate: Array | None = None  # the desired path's actuator rates this cycle
        self.freeze = float(freeze)
        self.motor_burst = bool(motor_burst)
        super().__init__(play_max, 0.0, start=start, fraction=fraction, learn=learn, window=window, rate=rate,
                         lead=lead)
        self.average_first = True  # the first reversals' estimates are averaged, then rate
        self.burst_first = False  # taking a first side is no reversal: no lead burst

    def reset(self, keep_estimate: bool = False) -> None:
        """Forget the sides, the observed output and (unless ``keep_estimate``) the learnt play."""
        super().reset(keep_estimate)
        self.output: Array | None = None
        self._stood = 0.0  # how long the desired path has stood still [s]
        self.wound = np.zeros(self.play_max.size)  # held back of the nominal command after a freeze
        self._held = np.zeros(self.play_max.size)  # the winding at the last frozen cycle
        self._seed: tuple[NDArray[np.bool_], Array] | None = None
        self._motor: Array | None = None  # the last encoder readings (micro-units)
        self._turns: list[tuple[float, NDArray[np.int_]]] = []  # (time [s], which turned) within buzz_time
        if not keep_estimate:
            self._fixed = np.zeros(self.play_max.size, bool)  # plays measured by a probe and not learnt any more
            self.motor_tau = np.full(self.play_max.size, math.nan)  # the motors' lags from a probe [s] (NaN: unknown)

    def seed(self, play: Array, output: Array, known: NDArray[np.bool_], relearn: bool = True,
             motor_tau: Array | None = None) -> None:
        """Start from a measured play [rad, m, ...] and output (motor units) where ``known``
        (a play probe, rig/loop/play_probe.py): the side is the edge the motor last pushed on, the
        learning goes on at its normal rate (``relearn``; else those plays stay as measured),
        no lead burst; elsewhere as after a reset. ``motor_tau``: the motors' first-order lags [s]
        the probe measured from the encoders (NaN where not), for ``motor_burst``."""
        self.reset(keep_estimate=True)
        if motor_tau is not None:
            tau = np.asarray(motor_tau, float)
            self.motor_tau = np.where(np.isfinite(tau) & (tau >= 0.0), tau, math.nan)
        k = np.asarray(known, bool)
        self._fixed = k & (not relearn)
        self.play = np.where(k, np.clip(np.asarray(play, float), 0.0, self.play_max), self.play)
        self._learnt = np.where(k, np.maximum(self._learnt, 1.0 / max(self.rate, 1e-9)), self._learnt)
        self._seed = (k, np.asarray(output, float).copy())

    def after_move(self, motor_before: Array, motor_after: Array) -> None:
        """The motors were moved from ``motor_before`` to ``motor_after`` [rad, m, ...] (encoder
        readings; the servo loop's start ramp): an actuator moved further than its play estimate
        ends with its output dragged at an edge of its band, not in its middle, and its first
        reversals are learnt at ``rate`` instead of averaged (replacing the low start at the first
        one). Measured, the mechanism not isolated: with the averaging, an arm ramped from home
        to the cube's start oscillated across its play on the walk's first edge (docs/notes/virtual-lab-timing.md,
        "the same start for both loops")."""
        moved = np.abs(on_micro_grid(motor_after) - on_micro_grid(motor_before)) > self.play
        self._learnt = np.where(moved, np.maximum(self._learnt, 1.0 / max(self.rate, 1e-9)), self._learnt)

    def observe(self, motor: Array) -> None:
        """Track the play's output from encoder readings ``motor`` [rad, m, ...], rounded to micro-units."""
        m = on_micro_grid(motor)
        self._motor = m
        half = 0.5 * self.play
        if self.output is None and self._seed is not None:  # a probe's output and side
            k, out = self._seed
            self._seed = None
            self.output = np.where(k, out, m)
            side = np.sign(on_micro_grid(m - self.output))
            self.direction = np.where(k, side, 0.0)
            self._off = self.direction * 0.5 * self.fraction * self.play
        self.output = m.copy() if self.output is None else np.clip(self.output, m - half, m + half)

    def offset(self, a_nom: Array, dt: float, a_dot_path: Array | None = None) -> Array:
        """:meth:`BacklashInverse.offset`; with ``motor_burst``, an actuator whose side just
        reversed and whose motor (the last encoder reading) has not reached the new side's edge of
        the band gets, instead of the lead's burst, the target that brings a first-order motor of
        the probed lag tau from where it is to the steady target u + side * fraction * b_hat / 2
        in one cycle: m + (goal - m) / (1 - exp(-dt / tau)), within the lead's largest offset.
        With ``release``, the winding held back after a freeze (:meth:`_unwind`) is taken off the
        nominal command first and off the offset returned."""
        self._unwind(np.asarray(a_nom, float), dt, a_dot_path)
        a_nom = np.asarray(a_nom, float) - self.wound
        return self._offset_of(a_nom, dt, a_dot_path) - self.wound

    @property
    def half(self) -> Array:
        """Half the largest offset per actuator [rad, m, ...]: the inversion's, plus what a
        release after a freeze may hold back (``release`` > 0)."""
        held = 0.5 * self.fraction * self.play_max if self.release > 0.0 else 0.0
        return np.asarray(super().half + held, float)

    def _unwind(self, a: Array, dt: float, a_dot_path: Array | None) -> None:
        """The path moves after standing past ``freeze`` (sides frozen): each actuator's nominal
        command ``a`` has been wound against its side inside the band by the feedback (the arm did
        not follow: the other actuators made up for it), and a change of side now would let the
        output jump by as much (the tip by J x that, at the walk's first cycle). That winding, a - y
        beyond the steady (1 - fraction) x b_hat / 2 of its side, within half the inverted bound, is
        held back and let out over ``release`` [s], so the feedback unwinds the others meanwhile."""
        if self.release <= 0.0:
            return
        moving = a_dot_path is not None and bool(np.any(np.abs(np.asarray(a_dot_path, float)) > 0.0))
        frozen = self.freeze > 0.0 and self._stood >= self.freeze - 1e-9
        if frozen and not moving and self.output is not None:  # the winding so far (before the path's step)
            d = self.direction
            steady = d * 0.5 * (1.0 - self.fraction) * self.play
            bound = 0.5 * self.fraction * self.play_max
            wound = np.where(d != 0.0, a - self.output - steady, 0.0)
            self._held = np.where(d * wound < 0.0, np.clip(wound, -bound, bound), 0.0)  # against the side only
        elif frozen and moving:
            self.wound = self._held
        elif dt > 0.0:
            self.wound = self.wound * math.exp(-dt / self.release)

    def _offset_of(self, a_nom: Array, dt: float, a_dot_path: Array | None) -> Array:
        old = self.direction.copy()
        burst = super().offset(a_nom, dt, a_dot_path)
        if not self.motor_burst or self._motor is None or self.output is None or dt <= 0.0:
            return burst
        d, m, tau = self.direction, self._motor, self.motor_tau
        crossing = (old != 0.0) & (d == -old) & np.isfinite(tau) & (d * (m - self.output) < 0.5 * self.play)
        if not np.any(crossing):
            return burst
        alpha = 1.0 - np.exp(-dt / np.where(np.isfinite(tau) & (tau > 0.0), tau, 1.0))
        alpha = np.where(np.isfinite(tau) & (tau > 0.0), alpha, 1.0)
        a = np.asarray(a_nom, float)
        goal = a + self._off  # the steady target (the lead's state is the steady offset)
        lim = super().half  # the inversion's own largest offset (not what a release holds back)
        sized = np.clip(m + (goal - m) / alpha - a, -lim, lim)
        return np.asarray(np.where(crossing, sized, burst), float)

    def _turn(self, a: Array) -> tuple[NDArray[np.bool_], Array]:
        """The side each actuator's motor pushes on: where the nominal command ``a`` left the band."""
        d = self.direction
        if self.output is None:
            return np.zeros(d.size, bool), d
        e = on_micro_grid(a - self.output)
        eps = self.margin * self.play_max
        new = np.where(e > eps, 1.0, np.where(e < -eps, -1.0, d))
        if self.freeze > 0.0 and self._stood >= self.freeze - 1e-9:  # a held point: noise must not walk
            return np.zeros(d.size, bool), np.where(d != 0.0, d, new)  # the motors across the band: sides stay
        flip = (new != d) & (d != 0.0)
        if self.buzz_time > 0.0 and np.any(flip):
            self._turns = [t for t in self._turns if t[0] > self.time - self.buzz_time]
            if self._path_rate is not None:
                recent = np.sum([f for _, f in self._turns], axis=0) if self._turns else np.zeros(d.size, int)
                unasked = ~(np.sign(self._path_rate) * new > 0.0)
                buzz = flip & unasked & (recent + 1 >= self.buzz_turns)
                floor = np.minimum(self.play, self.start * self.play_max)  # not under the learning's start
                self.play = np.where(buzz, np.maximum(self.buzz_shrink * self.play, floor), self.play)
                self.buzzes += int(np.count_nonzero(buzz))
            self._turns.append((self.time, flip.astype(int)))
        return flip, new

    def _learn(self, flip: NDArray[np.bool_], old: Array, new: Array) -> None:
        measured = self.play.copy()
        super()._learn(flip, old, new)
        self.play = np.where(self._fixed, measured, self.play)

    def _track_feedback(self, a: Array, dt: float, a_dot_path: Array | None) -> None:
        super()._track_feedback(a, dt, a_dot_path)
        self._path_rate = None if a_dot_path is None else np.asarray(a_dot_path, float)
        standing = a_dot_path is not None and not np.any(np.abs(np.asarray(a_dot_path, float)) > 0.0)
        self._stood = self._stood + dt if standing else 0.0
