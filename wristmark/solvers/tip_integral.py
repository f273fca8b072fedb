"""Integral of the tip error for the QP's position task (a constant-velocity disturbance observer).

The servo loop already integrates the controller's rates into the command, so proportional
feedback alone removes a constant position offset; what it leaves is a lag proportional to
the speed mismatch between the feed-forward and the true arm (gain errors of an arm the
controller was not tuned on, a load that grows along the path). The integral
v_i = ki * sum(e dt) [m/s] estimates that mismatch as a slowly varying velocity disturbance in
{w} and cancels it. Anti-windup: |v_i| is capped at ``limit`` [m/s], and the sum stops
growing while the proportional feedback is saturated (large errors are the proportional
term's job). For a later pose task the same class serves each task row block.

Path mode (:meth:`TipErrorIntegral.update_path`, ``integral_mode: path``): the mismatch is
assumed to be a linear map of the desired velocity (an arm's gain errors and cross-couplings:
the tip moves by M v instead of v), so it is learnt as v_i = ki G v_des with
dG = e v_des' / |v_des|^2 dt. Along a straight edge this is the plain integral; what one
direction taught stays in its own column of G, so at a corner the term turns with the path
instead of pushing on along the old edge (the plain integral's wind-up at a corner: it must
unlearn what it learnt and learn the new direction, both through the error), and on a reversal
it changes sign with the motion, as a gain error does. Assumed besides: G changes slowly along
the path (the Jacobian's gain errors vary over the workspace; each edge relearns its column);
a constant offset needs no integral (the loop integrates the proportional term); a path that
stands still neither learns nor adds anything (a held point is the proportional term's).
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
        self.gain = np.zeros((self.dim, self.dim))  # path mode's G [s]: v_i = ki G v_des

    def update_path(self, error: Array, v_des: Array | None, dt: float, saturated: bool = False) -> Array:
        """Path mode: add ``error`` [m] over ``dt`` [s] along the desired velocity ``v_des`` [m/s]
        (unless ``saturated``; nothing while the path stands still or is None); the velocity term
        ki G v_des [m/s], capped at ``limit`` with G scaled back to the cap (no wind-up)."""
        if self.ki == 0.0 or v_des is None:
            return np.zeros(self.dim)
        v = np.asarray(v_des, float)
        n2 = float(v @ v)
        if n2 < 1e-10:  # below 10 um/s: a held point
            return np.zeros(self.dim)
        if not saturated:
            self.gain = self.gain + np.outer(np.asarray(error, float), v) * (dt / n2)
        out = self.ki * self.gain @ v
        n = float(np.linalg.norm(out))
        if n > self.limit:
            out *= self.limit / n
            self.gain = self.gain * (self.limit / n)
        return np.asarray(out, float)

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
