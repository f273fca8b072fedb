"""What drives and what is driven: the interface between an actuator source and an arm.

The actuator-box emulator, the in-process servo loop and the tests talk to any object with
this interface; :class:`sim.plant.TruePlant` is the simulated true arm that implements it.
Actuator coordinates a = [phi, d, s1a, s1b, s2a, s2b] in [rad, m, m, m, m, m].
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_shape import ArmShape

Array = NDArray[np.float64]


class ActuatedArm(Protocol):
    """An arm moved by six actuators, advanced in time by the caller."""

    def command(self, actuators: Array) -> None:
        """Set the six actuator targets [rad, m, m, m, m, m]; motors move towards them."""

    def hold(self) -> None:
        """Freeze the targets at the current measured positions (stop moving)."""

    def advance(self, dt: float) -> None:
        """Advance the physical state by ``dt`` seconds."""

    def measured_actuators(self) -> Array:
        """Current actuator positions as the encoders read them [rad, m, m, m, m, m]."""

    def true_shape(self) -> ArmShape:
        """The arm's true shape now (what cameras see and the optical tracker measures)."""

    @property
    def time(self) -> float:
        """Simulated time since creation [s]."""
