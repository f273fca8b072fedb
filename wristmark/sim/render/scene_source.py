"""One simulated endoscope seeing several arms: one rendered frame per instant, shared by the arms.

:class:`SceneFrames` renders every arm's true shape (moved by its base pose into the scene's {w})
into one stereo pair with :meth:`StereoRenderer.render_arms` (mutual occlusion included), at most
once per instant: :meth:`SceneFrames.feed` gives each arm's servo loop its own frame feed, which
asks for the frame at that arm's clock; the arms' loops step in lockstep (sim.several_arms), so
they all see the same frame. ``last_scene`` keeps the last render's ground truth.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.arm_shape import ArmShape, transformed
from wristmark.models.marker import MarkerModel
from wristmark.models.plant_interface import ActuatedArm
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import RenderedScene, StereoRenderer

Array = NDArray[np.float64]

__all__ = ["SceneFrames"]


class SceneFrames:
    """Renders ``arms`` (each with its base pose in the scene's {w}, 4x4 [m]) through ``camera``
    (``world_T_left`` in the scene's {w}) with their ``markers``; ``noise``, ``seed``, ``gloss``
    and ``age`` as :class:`sim.render.rendered_source.RenderedStereoSource`."""

    def __init__(self, arms: Sequence[ActuatedArm], bases: Sequence[Array], camera: StereoCamera,
                 markers: Sequence[MarkerModel], noise: str = "default", seed: int = 0, age: float = 0.0,
                 gloss: tuple[float, float] = (0.0, 0.1), name: str = "simulated endoscope") -> None:
        self.arms, self.bases = list(arms), [np.asarray(b, float) for b in bases]
        self.age = float(age)
        self.name = name
        spec, rough = gloss
        self.renderer = StereoRenderer(camera, list(markers), noise_preset(noise, sleeve_specular=spec,
                                                                          sleeve_roughness=rough), seed=seed)
        self.last_scene: RenderedScene | None = None
        self._t: float | None = None
        self._frame: StereoFrame | None = None
        self._index = 0

    def shapes(self) -> list[ArmShape]:
        """Every arm's true shape now (``age`` ago) in the scene's {w}."""
        out = []
        for arm, base in zip(self.arms, self.bases):
            shape = arm.true_shape_at(arm.time - self.age) if self.age > 0 else arm.true_shape()  # type: ignore[attr-defined]
            out.append(transformed(shape, base))
        return out

    def frame_at(self, t: float) -> StereoFrame:
        """The frame of instant ``t`` [s] (rendered on the first call for it; stamped ``t - age``)."""
        if self._frame is None or self._t != t:
            scene = self.renderer.render_arms(self.shapes())
            self.last_scene = scene
            self._frame = StereoFrame(scene.left, scene.right, t - self.age, self._index, self.name, self.name)
            self._index += 1
            self._t = t
        return self._frame

    def feed(self, clock: Callable[[], float]) -> _ArmFeed:
        """A frame feed for one arm's loop: each take is the frame at ``clock()`` (its loop's time)."""
        return _ArmFeed(self, clock)


class _ArmFeed:
    """One arm's :class:`rig.loop.frame_feed.FrameFeed` on a shared :class:`SceneFrames`."""

    def __init__(self, frames: SceneFrames, clock: Callable[[], float]) -> None:
        self.frames, self.clock = frames, clock
        self.name = frames.name
        self.last_arrival = float("nan")
        self.dropped = 0

    def take(self, fresh_after: float = -np.inf, wait_until: float = -np.inf) -> StereoFrame | None:
        """The scene's frame at this arm's time."""
        return self.frames.frame_at(float(self.clock()))

    def close(self) -> None:
        """Nothing to release."""
