"""The simulated bench's explicit fast option (``sensor: truth-noise``): the true tip plus noise.

It is not vision: :class:`TruthClockSource` hands out empty frames that only carry their
capture time, and :class:`NoisyTruthSensor` reads the true arm at that instant (simulated time
stands still while the loop processes a frame). It exists for fast tests and sweeps and never
runs unless asked for; the hardware path cannot use it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.plant_interface import ActuatedArm
from wristmark.models.so3 import perturb
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.sim.render.rendered_source import OnDemandSource

Array = NDArray[np.float64]
_EMPTY = np.zeros((1, 1), np.uint8)


class TruthClockSource(OnDemandSource):
    """Frames without pixels (1x1), stamped with ``clock()`` [s]: the instants of the truth."""

    def __init__(self, clock: Callable[[], float], name: str = "truth-noise") -> None:
        super().__init__(clock, name)

    def read(self) -> StereoFrame:
        """An empty frame stamped now."""
        return self._frame(float(self.clock()), _EMPTY, _EMPTY)


class NoisyTruthSensor:
    """The true tip of ``arm`` plus isotropic Gaussian noise of 3D RMS ``rms`` [m], and the true
    tip frame's orientation turned by a random rotation of RMS angle ``rotation_rms`` [rad]
    (drawn from its own stream, so the position noise is the same with or without it). Its
    measurements report that noise's standard deviation along each axis as their tip sigma."""

    def __init__(self, arm: ActuatedArm, rms: float, seed: int = 0, rotation_rms: float = np.deg2rad(0.2)) -> None:
        self.arm = arm
        self._sigma = rms / np.sqrt(3.0)
        self._rng = np.random.default_rng(seed)
        self._rot_rng = np.random.default_rng([seed, 1])
        self.rotation_rms = float(rotation_rms)

    def measure(self, frame: StereoFrame, axis_hint_world: Array | None = None) -> TipMeasurement:
        """True tip + noise at the frame's instant, with the full orientation (roll known); never
        fails (the hint is not needed). The marker's pose: the true one moved rigidly with the
        tip frame's noise (the noisy tip frame times the true tip-to-marker transform)."""
        shape = self.arm.true_shape()
        p = shape.tip + self._rng.normal(0.0, self._sigma, 3)
        T_tip = shape.frames.T_world_tip
        R = perturb(T_tip[:3, :3], self._rot_rng, self.rotation_rms)
        noisy = np.eye(4)
        noisy[:3, :3], noisy[:3, 3] = R, p
        T_marker = noisy @ np.linalg.inv(T_tip) @ shape.frames.T_world_marker
        return TipMeasurement(True, p, t_capture=frame.t_capture, frame_index=frame.index, R_world=R,
                              roll_known=True, T_world_marker=T_marker, tip_sigma_m=float(self._sigma))
