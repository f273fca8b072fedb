"""The arm's true tip motion against the nominal model's, learnt from the camera's own measurements.

The delay compensation (rig/loop/delay_compensation.py) moves a measured tip on by the nominal
model's predicted motion from the frame's capture to the cycle's start. A real arm does not move
as its model says (bending gains, plane offsets, a stiffer or softer segment): over a gap of
``a`` seconds at a tip speed ``v`` the prediction is off by the model's error times ``v * a``, a
bias that grows with the frames' age and that the loop's feedback cannot see (it acts on the
compensated measurement). At 10 mm/s and 100 ms that is ~0.03 mm for a 6 % gain error.

:class:`MotionCorrection` fits the 3x3 map ``M`` from the model's motion to the measured motion
between consecutive accepted measurements (``dp_measured ~ M dp_model``), by recursive least
squares with exponential forgetting (time constant ``window`` [s]) and a ridge prior towards the
identity of weight ``prior`` [m^2] (a held arm, or motion along one axis only, leaves ``M`` near
the identity in the directions not excited). Every entry of ``M - I`` is clipped to
``+-max_deviation``. The compensation then adds ``M dp_model``. Measurement noise enters only the
measured side, so it does not bias the fit. Positions in {w} [m], times [s] on the loop's clock.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class MotionCorrection:
    """Recursive ridge fit of measured tip motion against the model's, in {w} [m].

    window: forgetting time constant [s] (> 0); prior: weight of the identity prior [m^2]
    (~ that many squared metres of model motion); max_deviation: largest |M - I| entry [-];
    max_gap: consecutive measurements further apart than this [s] are not paired."""

    def __init__(self, window: float = 5.0, prior: float = 1e-5, max_deviation: float = 0.3,
                 max_gap: float = 0.5) -> None:
        if not (math.isfinite(window) and window > 0):
            raise ValueError(f"window must be > 0 s, got {window}")
        if not (math.isfinite(prior) and prior > 0):
            raise ValueError(f"prior must be > 0 m^2, got {prior}")
        self.window = float(window)
        self.prior = float(prior)
        self.max_deviation = float(max_deviation)
        self.max_gap = float(max_gap)
        self.reset()

    def reset(self) -> None:
        """Forget everything: M = I."""
        self._A = np.zeros((3, 3))  # sum of dp_model dp_model^T, forgotten
        self._B = np.zeros((3, 3))  # sum of dp_measured dp_model^T, forgotten
        self._last: tuple[Array, float] | None = None
        self.matrix: Array = np.eye(3)
        self.updates = 0

    def observe(self, p_measured: Array, t_capture: float, model_motion: Array | None) -> None:
        """An accepted measurement ``p_measured`` [m] captured at ``t_capture`` [s];
        ``model_motion``: the model's tip motion [m] from the previous measurement's capture to
        this one (None: no previous measurement, or unknown). A measurement no newer than the
        last is ignored (a reused one)."""
        p = np.asarray(p_measured, float)
        if not (np.all(np.isfinite(p)) and math.isfinite(t_capture)):
            return
        last = self._last
        if last is not None and t_capture <= last[1]:
            return
        self._last = (p.copy(), float(t_capture))
        if last is None or model_motion is None or t_capture - last[1] > self.max_gap:
            return
        dm, dp = p - last[0], np.asarray(model_motion, float)
        if not np.all(np.isfinite(dp)):
            return
        keep = math.exp(-(t_capture - last[1]) / self.window)
        self._A = keep * self._A + np.outer(dp, dp)
        self._B = keep * self._B + np.outer(dm, dp)
        eye = np.eye(3)
        M = (self._B + self.prior * eye) @ np.linalg.inv(self._A + self.prior * eye)
        self.matrix = eye + np.clip(M - eye, -self.max_deviation, self.max_deviation)
        self.updates += 1

    @property
    def last_capture(self) -> float:
        """The capture time [s] of the last measurement observed (-inf before any)."""
        return self._last[1] if self._last is not None else -math.inf

    def apply(self, model_motion: Array) -> Array:
        """The model's tip motion [m] corrected: ``M @ model_motion``."""
        return self.matrix @ np.asarray(model_motion, float)
