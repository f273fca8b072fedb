"""A simulated arm shared between threads: the emulator's thread advances it while the
simulated cameras render it and the ground-truth observer reads it."""

from __future__ import annotations

import threading

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_shape import ArmShape
from wristmark.models.plant_interface import ActuatedArm

Array = NDArray[np.float64]


class LockedArm:
    """An :class:`ActuatedArm` whose every call holds one lock: the emulator's thread advances
    the arm while the loop's cameras read its shape."""

    def __init__(self, arm: ActuatedArm, lock: threading.RLock | None = None) -> None:
        self.arm = arm
        self.lock = lock if lock is not None else threading.RLock()

    def command(self, actuators: Array) -> None:
        """Set targets [rad, m, m, m, m, m]."""
        with self.lock:
            self.arm.command(actuators)

    def hold(self) -> None:
        """Freeze the targets at the current positions."""
        with self.lock:
            self.arm.hold()

    def advance(self, dt: float) -> None:
        """Advance by ``dt`` [s]."""
        with self.lock:
            self.arm.advance(dt)

    def measured_actuators(self) -> Array:
        """Encoder positions [rad, m, m, m, m, m]."""
        with self.lock:
            return self.arm.measured_actuators()

    def true_shape(self) -> ArmShape:
        """The true shape now."""
        with self.lock:
            return self.arm.true_shape()

    def true_shape_at(self, t: float) -> ArmShape:
        """The true shape at the earlier instant ``t`` [s] (an arm that keeps a history:
        :meth:`sim.plant.TruePlant.true_shape_at`)."""
        with self.lock:
            return self.arm.true_shape_at(t)  # type: ignore[attr-defined]

    @property
    def true_psi(self) -> Array:
        """The true configuration (NaN when the arm does not expose it)."""
        with self.lock:
            return np.asarray(getattr(self.arm, "true_psi", np.full(6, np.nan)), float)

    @property
    def time(self) -> float:
        """The arm's time [s]."""
        with self.lock:
            return self.arm.time


