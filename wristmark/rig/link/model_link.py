"""A link that commands the identified arm's inverse (``--model``, docs/identification.md).

Between the servo loop and the real link: every target the loop sends (actuator values of the
nominal model's configuration) becomes the configuration at which the identified arm (a plant
file fitted by ``wristmark identify``) puts its tip where the nominal model would
(models/plant_map.py ``plant_command``); the encoder readings handed back are shifted by that
correction, so the loop, its controller and the controller's dead-band inversion see an arm that
behaves as the nominal model (their feed-forward and Jacobian are then the identified arm's).
The identified plays are inverted (``plays``: each actuator's target offset by half its play on
the side it last moved to, the side changing once the target came back REVERSAL x the play),
then the motors' lag: each target becomes the one that brings a first-order motor from its
encoder reading to the target in one control cycle (a motor that trails the path by tau x its
speed turns a cube's corner 1 mm off), sent for that cycle only. Actuator values [rad, m, ...],
time [s].
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm
from wristmark.models.plant_map import plant_command
from wristmark.models.plant_params import PlantParams
from wristmark.rig.link.actuator_link import ActuatorLink

Array = NDArray[np.float64]
__all__ = ["ModelLink"]

REVERSAL = 0.1  # x the play: how far an actuator's target must come back before its side changes


class ModelLink:
    """:class:`rig.link.actuator_link.ActuatorLink` through the identified arm's inverse: its
    static map always, the motors' lag (targets sent every ``cycle`` [s]) always, the plays when
    ``plays`` (open loop)."""

    def __init__(self, link: ActuatorLink, params: Arm, model: PlantParams, cycle: float, plays: bool = False) -> None:
        self.link = link
        self.params = params
        self.model = model
        self.cycle = float(cycle)
        self.plays = bool(plays)
        self._shift: Array | None = None  # nominal - corrected actuators of the last target
        self._hint: Array | None = None
        self._plain: Array | None = None  # the target without the lag's inversion, due a cycle after it
        self._sent_at = -math.inf
        self._side: Array | None = None
        self._turn: Array | None = None  # per actuator the extreme since its last reversal

    @property
    def wrapped(self) -> ActuatorLink:
        """The link it commands through (rig.link.actuator_link.box_actuators)."""
        return self.link

    @property
    def time(self) -> float:
        """The inner link's time [s]."""
        return self.link.time

    def advance_to(self, t: float) -> None:
        """Let the world run to ``t`` [s]; a lag-inverting target is sent for one cycle only,
        then the plain one (a loop that holds a target for longer does not hold an overshoot)."""
        if self._plain is not None and t > self._sent_at + self.cycle + 1e-9:
            self.link.advance_to(self._sent_at + self.cycle)
            self.link.send_target(self._plain)
            self._plain = None
        self.link.advance_to(t)

    def corrected(self, actuators: Array) -> Array:
        """The actuator values at which the identified arm reaches what the nominal model reaches
        at ``actuators`` (no play, no lag)."""
        a = np.asarray(actuators, float)
        psi = psi_from_actuators(self.params, a, delta_hint=self._hint)
        self._hint = psi
        return actuators_from_psi(self.params, plant_command(self.params, self.model, psi))

    def send_target(self, actuators: Array) -> None:
        """Send the identified arm's inverse of the nominal targets ``actuators``."""
        a_nom = np.asarray(actuators, float)
        a = self.corrected(a_nom)
        self._shift = a_nom - a
        goal = a + self._play_offset(a) if self.plays else a
        out = self._lag_inverse(goal)
        self._plain, self._sent_at = (goal if np.any(out != goal) else None), self.link.time
        self.link.send_target(out)

    def _play_offset(self, a: Array) -> Array:
        """Half the identified play on the side each actuator last moved to (a reversal counts
        once the target came back REVERSAL x the play from its extreme)."""
        b = np.asarray(self.model.backlash, float)
        if self._side is None or self._turn is None:  # the first target: the motors will move towards it
            gap = a - np.asarray(self.link.measured_actuators(), float)
            self._side = np.where(np.abs(gap) > REVERSAL * b, np.sign(gap), 0.0)
            self._turn = a.copy()
            return 0.5 * b * self._side
        up = (self._side > 0) & (a > self._turn)
        down = (self._side < 0) & (a < self._turn)
        self._turn = np.where(up | down, a, self._turn)
        flip_up = (self._side <= 0) & (a > self._turn + REVERSAL * b)
        flip_down = (self._side >= 0) & (a < self._turn - REVERSAL * b)
        self._side = np.where(flip_up, 1.0, np.where(flip_down, -1.0, self._side))
        self._turn = np.where(flip_up | flip_down, a, self._turn)
        return 0.5 * b * self._side

    def _lag_inverse(self, goal: Array) -> Array:
        """The target that brings a first-order motor of the identified lag from its reading now
        to ``goal`` in one cycle: m + (goal - m) / (1 - exp(-dt / tau)) (``goal`` without a lag)."""
        tau = self.model.actuator_tau
        if tau <= 0 or self.cycle <= 0:
            return goal
        m = np.asarray(self.link.measured_actuators(), float)
        return m + (goal - m) / (1.0 - math.exp(-self.cycle / tau))

    def hold(self) -> None:
        """Hold the actuators."""
        self._plain = None
        self.link.hold()

    def measured_actuators(self) -> Array:
        """The encoders as the nominal model sees them (shifted by the last target's correction)."""
        enc = np.asarray(self.link.measured_actuators(), float)
        return enc if self._shift is None else enc + self._shift

    def close(self) -> None:
        """Close the inner link."""
        self.link.close()
