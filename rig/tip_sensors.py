"""Where the servo loop's tip measurement comes from.

``VisionTipSensor`` is the default and the real thing: it renders the stereo endoscope's
images of the true arm and runs the marker tracker on the pixels. ``NoisyTruthSensor`` is an
explicit fast option (``sensor: truth-noise``) that never runs unless asked for.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from cvs.camera import StereoCamera
from cvs.marker import MarkerModel
from models.arm_shape import ArmShape

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TipMeasurement:
    """One tip measurement in {w} [m]; ``ok`` False with a ``reason`` when there is none."""

    ok: bool
    p_world: Array | None
    reason: str = ""
    time_ms: float = 0.0
    rms_px: float = float("nan")


class TipSensor(Protocol):
    """Anything that measures the tip of the arm from its true shape."""

    def measure(self, shape: ArmShape, axis_hint_world: Array | None = None) -> TipMeasurement:
        """Measure the tip of ``shape`` (the true arm now); ``axis_hint_world``: the expected
        direction of the marker's z axis in {w} (e.g. the model's at the commanded configuration)."""


class NoisyTruthSensor:
    """The true tip plus isotropic Gaussian noise of 3D RMS ``rms`` [m] (fast option)."""

    def __init__(self, rms: float, seed: int = 0) -> None:
        self._sigma = rms / np.sqrt(3.0)
        self._rng = np.random.default_rng(seed)

    def measure(self, shape: ArmShape, axis_hint_world: Array | None = None) -> TipMeasurement:
        """True tip + noise; never fails (the hint is not needed)."""
        p = shape.tip + self._rng.normal(0.0, self._sigma, 3)
        return TipMeasurement(True, p)


class VisionTipSensor:
    """Render the stereo pair of the true arm, track the marker in it, return the tip in {w}.

    ``camera`` renders (where the endoscope truly is); ``host_camera`` (default: the same) is what
    the host believes: its tracker maps {ll} to {w} with the host's world_T_left."""

    def __init__(
        self, camera: StereoCamera, marker: MarkerModel, noise: str = "default", seed: int = 0,
        host_camera: StereoCamera | None = None,
    ) -> None:
        from cvs.marker_tracker import MarkerTracker
        from sim.render import StereoRenderer
        from sim.render_settings import noise_preset

        self.camera = camera if host_camera is None else host_camera
        self.renderer = StereoRenderer(camera, marker, noise_preset(noise), seed=seed)
        self.tracker = MarkerTracker(self.camera, marker)
        self.last_images: tuple[np.ndarray, np.ndarray] | None = None

    def measure(self, shape: ArmShape, axis_hint_world: Array | None = None) -> TipMeasurement:
        """Render + track; the time reported is the tracking time only [ms]. The axis hint picks
        which way the marker points (its pattern is symmetric under a half turn)."""
        frame = self.renderer.render(shape)
        self.last_images = (frame.left, frame.right)
        hint = None
        if axis_hint_world is not None and self.camera.T_world_left is not None:
            hint = np.asarray(self.camera.T_world_left, float)[:3, :3].T @ np.asarray(axis_hint_world, float)
        t0 = time.perf_counter()
        res = self.tracker.track(frame.left, frame.right, axis_hint_left=hint)
        ms = 1000.0 * (time.perf_counter() - t0)
        if not res.ok or res.tip_world is None:
            return TipMeasurement(False, None, res.reason or "marker not found", ms)
        return TipMeasurement(True, np.asarray(res.tip_world, float), "", ms, float(res.rms_px))
