"""Simulated optical tracker (the paper's Polaris Vega): a 6-DoF tool pose with Gaussian noise.

Noise model: the tip position gets isotropic Gaussian noise of 3D RMS ``rms`` [m] (per-axis
sigma rms / sqrt(3); Polaris Vega: 0.12 mm RMS); the tool frame's orientation is turned by
Exp(n) in {w}, n isotropic Gaussian with per-axis sigma rotation_rms / sqrt(3), so the RMS
angle of the orientation error is ``rotation_rms`` [rad] (Polaris Vega class: ~0.2 deg). The
two are independent and drawn from separate streams of one seed (the position noise is the same
whether or not the orientation is measured); no bias, no correlation over time.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.models.so3 import perturb

Array = NDArray[np.float64]
VEGA_POSITION_RMS = 0.12e-3  # [m]
VEGA_ROTATION_RMS = float(np.deg2rad(0.2))  # [rad]


class OpticalTracker:
    """Measures a point, or a point and a frame, with the noise of the module docstring."""

    def __init__(self, rms: float = VEGA_POSITION_RMS, seed: int = 0, rotation_rms: float = VEGA_ROTATION_RMS) -> None:
        if not rms >= 0:
            raise ValueError(f"tracker rms must be >= 0 m, got {rms}")
        if not rotation_rms >= 0:
            raise ValueError(f"tracker rotation rms must be >= 0 rad, got {rotation_rms}")
        self.rms = rms
        self.rotation_rms = float(rotation_rms)
        self._sigma = rms / np.sqrt(3.0)
        self._rng = np.random.default_rng(seed)
        self._rot_rng = np.random.default_rng([seed, 1])

    def measure(self, p_true: Array) -> Array:
        """Noisy measurement of the point ``p_true`` (3,) in {w} [m]."""
        return np.asarray(p_true, float) + self._rng.normal(0.0, self._sigma, 3)

    def measure_pose(self, p_true: Array, R_true: Array) -> tuple[Array, Array]:
        """Noisy measurement of a tool at ``p_true`` (3,) [m] with orientation ``R_true`` (3x3),
        both in {w}: (position, rotation)."""
        return self.measure(p_true), perturb(R_true, self._rot_rng, self.rotation_rms)
