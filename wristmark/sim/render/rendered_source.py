"""The simulated stereo endoscope as a frame source: each read renders the true arm now.

:class:`RenderedStereoSource` implements :class:`cvs.sources.frames.StereoSource` on the simulated
bench: ``read()`` renders the arm's true shape at this instant and stamps the frame with the
given clock (the loop's simulated time in process; ``time.monotonic()`` in the virtual lab's
camera). It never ends and never drops a frame.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.marker import MarkerModel
from wristmark.models.plant_interface import ActuatedArm
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer


class OnDemandSource:
    """Base of the bench's sources that make a frame when asked: never end, never drop."""

    def __init__(self, clock: Callable[[], float], name: str) -> None:
        self.clock = clock
        self.name = name
        self._index = 0

    def _frame(self, t: float, left: NDArray[np.uint8], right: NDArray[np.uint8]) -> StereoFrame:
        """The next frame, captured at ``t`` [s]."""
        frame = StereoFrame(left, right, t, self._index, self.name, self.name)
        self._index += 1
        return frame

    @property
    def dropped(self) -> int:
        """Always 0: frames are made on demand."""
        return 0

    def close(self) -> None:
        """Nothing to release."""


class RenderedStereoSource(OnDemandSource):
    """Renders ``arm`` through ``camera`` (noise preset ``noise``, seeded) at every read;
    ``gloss``: the sleeve's laminate (F0, GGX roughness; RenderSettings.sleeve_specular, F0 0: matte).

    age: each frame shows the arm as it was this long [s] before the read, and is stamped so
    (a camera whose frames reach the host that late; the arm must keep that much history:
    ``true_shape_at``, e.g. :class:`sim.plant.TruePlant` with ``history``)."""

    def __init__(self, arm: ActuatedArm, camera: StereoCamera, marker: MarkerModel, clock: Callable[[], float],
                 noise: str = "default", seed: int = 0, name: str = "simulated endoscope", age: float = 0.0,
                 gloss: tuple[float, float] = (0.0, 0.1)) -> None:
        super().__init__(clock, name)
        self.arm = arm
        self.age = float(age)
        spec, rough = gloss
        self.renderer = StereoRenderer(camera, marker, noise_preset(noise, sleeve_specular=spec,
                                                                   sleeve_roughness=rough), seed=seed)
        self.last_pair: RenderedPair | None = None

    def read(self) -> StereoFrame:
        """Render the true arm now (``age`` ago); t_capture = the clock now (minus ``age``) [s]."""
        t = float(self.clock())
        if self.age > 0:
            shape = self.arm.true_shape_at(self.arm.time - self.age)  # type: ignore[attr-defined]
            t -= self.age
        else:
            shape = self.arm.true_shape()
        pair = self.renderer.render(shape)
        self.last_pair = pair
        return self._frame(t, pair.left, pair.right)
