"""Integral of the tip error for the QP's position task (a constant-velocity disturbance observer).

The servo loop already integrates the controller's rates into the command, so proportional
feedback alone removes a constant position offset; what it leaves is a lag proportional to
the speed mismatch between the feed-forward and the true arm (gain errors of an arm the
controller was not tuned on, a load that grows along the path). The integral
v_i = ki * sum(e dt) [m/s] estimates that mismatch as a slowly varying velocity disturbance in
{w} and cancels it. Anti-windup: |v_i| is capped at ``limit`` [m/s], and the sum stops
growing while the proportional feedback is saturated (large errors are the proportional
term's job). For a later pose task the same class serves each task row block.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class TipErrorIntegral:
    """Clamped, conditionally integrated tip error; output a velocity [m/s] in {w}."""

    def __init__(self, ki: float, limit: float, dim: int = 3) -> None:
        self.ki = float(ki)
        self.limit = float(limit)
        self.dim = dim
        self.reset()

    def reset(self) -> None:
        """Zero the integral."""
        self.sum = np.zeros(self.dim)  # [m s]

    def update(self, error: Array, dt: float, saturated: bool = False) -> Array:
        """Add ``error`` [m] over ``dt`` [s] (unless ``saturated``); the velocity term [m/s]."""
        if self.ki == 0.0:
            return np.zeros(self.dim)
        if not saturated:
            self.sum = self.sum + np.asarray(error, float) * dt
        v = self.ki * self.sum
        n = float(np.linalg.norm(v))
        if n > self.limit:  # cap the output and keep the state at the cap (no windup)
            v *= self.limit / n
            self.sum = v / self.ki
        return v
