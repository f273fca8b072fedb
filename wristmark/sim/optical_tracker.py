"""Simulated optical tracker (the paper's Polaris Vega): the true tip with Gaussian noise."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class OpticalTracker:
    """Measures a point with isotropic Gaussian noise of 3D RMS ``rms`` [m].

    Per-axis sigma = rms / sqrt(3), so E|noise|^2 = rms^2 (Polaris Vega: 0.12 mm RMS).
    """

    def __init__(self, rms: float = 0.12e-3, seed: int = 0) -> None:
        if rms < 0:
            raise ValueError(f"tracker rms must be >= 0 m, got {rms}")
        self.rms = rms
        self._sigma = rms / np.sqrt(3.0)
        self._rng = np.random.default_rng(seed)

    def measure(self, p_true: Array) -> Array:
        """Noisy measurement of the point ``p_true`` (3,) in {w} [m]."""
        return np.asarray(p_true, float) + self._rng.normal(0.0, self._sigma, 3)
