"""How commands reach the arm and simulated time moves on.

``DirectLink`` calls the simulated plant in process. ``SerialLink`` sends every command as
protocol-v1 bytes through a serial device (a pseudo-terminal to the emulator, or hardware);
with the in-process emulator the simulated clock is shared, so the loop runs faster than real
time and the bytes still cross a real pty.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from wristmark.models.plant_interface import ActuatedArm

Array = NDArray[np.float64]


class ActuatorLink(Protocol):
    """The servo loop's view of the actuators and of time: configurations psi [rad, m, rad, rad,
    rad, rad], time [s]."""

    @property
    def time(self) -> float:
        """The link's time now [s] (simulated, or the wall clock's for a real-time link)."""
        ...

    def advance_to(self, t: float) -> None:
        """Let the world run until time ``t`` [s] (a real-time link waits until then)."""

    def send_target(self, actuators: Array) -> None:
        """Command actuator targets [rad, m, m, m, m, m] now."""

    def hold(self) -> None:
        """Stop: hold the current position."""

    def measured_actuators(self) -> Array:
        """Encoder readings [rad, m, m, m, m, m]."""

    def close(self) -> None:
        """Leave the actuators safe (held and disabled where that applies)."""


class DirectLink:
    """In-process link to a simulated arm (no bytes): psi [rad, m, ...], the arm's own time [s]."""

    def __init__(self, arm: ActuatedArm) -> None:
        self.arm = arm
        self.last_target: Array | None = None

    @property
    def time(self) -> float:
        """The plant's simulated time [s]."""
        return self.arm.time

    def advance_to(self, t: float) -> None:
        """Step the plant to time ``t`` [s]."""
        dt = t - self.arm.time
        if dt > 0:
            self.arm.advance(dt)

    def send_target(self, actuators: Array) -> None:
        """Set the plant's actuator targets."""
        self.last_target = np.array(actuators, float)
        self.arm.command(self.last_target)

    def hold(self) -> None:
        """Hold the plant."""
        self.arm.hold()

    def measured_actuators(self) -> Array:
        """Plant encoders."""
        return self.arm.measured_actuators()

    def close(self) -> None:
        """Hold the plant."""
        self.arm.hold()


def box_actuators(link: object) -> tuple[Array | None, Array | None]:
    """What the actuator box behind ``link`` last saw, without any I/O: the target last sent to it
    and its latest encoder readings [rad or m each] (through any wrapping link, e.g. ``--model``'s
    rig.link.model_link.ModelLink, to the innermost one); None where the link does not say."""
    while (inner := getattr(link, "wrapped", None)) is not None:
        link = inner
    target = getattr(link, "last_target", None)
    if isinstance(link, DirectLink):
        reading: Array | None = np.asarray(link.arm.measured_actuators(), float).copy()
    else:
        state = getattr(link, "state", None)
        reading = np.asarray(state.positions, float).copy() if state is not None else None
    return (None if target is None else np.asarray(target, float).copy()), reading
