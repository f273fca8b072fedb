"""The virtual lab of a scene over ROS 2 (``wristmark emulator --scene SCENE --ros2 [NS]``): each
arm of a scene (sim.scene_setup) behind its own topics under ``NS/NAME`` (``servo_jp``,
``crtk_command`` in; ``measured_js``, ``operating_state`` out: the one-arm lab's
:class:`sim.ros2_lab.Ros2Arm`, its own watchdog), at its base pose in the scene's {w}, and one
stereo endoscope on ``NS/left/image_raw/compressed`` and ``NS/right/image_raw/compressed``
rendering every arm into each frame (the arms hide one another). One participant, loopback
unless ``CYCLONEDDS_URI`` says otherwise. ``truth_out``: each frame's instant and every arm's true
tip in the scene's {w} (sim.scene_lab's header)."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.models.arm_shape import transformed
from wristmark.rig.ros2.bridge import clean_namespace
from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds
from wristmark.rig.ros2.scene_bridge import arm_namespace
from wristmark.sim.ros2_lab import Ros2Arm, Ros2Endoscope, check_camera, open_truth
from wristmark.sim.scene_lab import scene_truth_header
from wristmark.sim.scene_setup import SceneSetup


class Ros2SceneLab:
    """Every arm of ``setup`` under ``NS/NAME`` and one endoscope under ``NS`` (module docstring)."""

    def __init__(self, setup: SceneSetup, namespace: str = "lab", fps: float = 15.0, image_scale: float = 0.35,
                 noise: str = "default", seed: int = 0, jpeg_quality: int = 90, watchdog_s: float = 0.25,
                 truth_out: str | Path | None = None) -> None:
        require_cyclonedds("the virtual lab over ROS 2")
        check_camera(fps, image_scale)
        self.namespace = clean_namespace(namespace)
        self.names = list(setup.names)
        self.arms = {n: Ros2Arm(setup.arms[n].params, setup.arms[n].plant, arm_namespace(namespace, n), watchdog_s)
                     for n in self.names}
        self.bases = {n: np.asarray(setup.base(n), float) for n in self.names}
        cam = setup.camera
        self.camera: StereoCamera = cam if image_scale == 1.0 else scaled_stereo_camera(cam, image_scale)
        self.endoscope = Ros2Endoscope(self.camera, list(setup.markers), namespace, fps, self._sample, noise, seed,
                                       jpeg_quality)
        self.truth_path = Path(truth_out) if truth_out else None
        self.participant: Any = None
        self._stop = threading.Event()
        self._camera: threading.Thread | None = None

    def _sample(self) -> tuple[float, list[Any]]:
        """Every arm advanced to now, its shape in the scene's {w}."""
        samples = [self.arms[n].advance() for n in self.names]
        return samples[0][0], [transformed(shape, self.bases[n]) for n, (_, shape) in zip(self.names, samples)]

    @property
    def error(self) -> str:
        """The first arm's or the endoscope's failure ("" while every part runs)."""
        return self.endoscope.error or next((a.error for a in self.arms.values() if a.error), "")

    def count(self, what: str) -> int:
        """An arm counter (targets, watchdog_trips, malformed) summed over the arms."""
        return sum(int(getattr(a, what)) for a in self.arms.values())

    def topics(self) -> dict[str, str]:
        """The host's SPECs: {arm: ``ros2:/NS/NAME``} and ``camera``: ``ros2:LEFT,RIGHT``."""
        ns = self.namespace
        return {**{n: f"ros2:{a.namespace}" for n, a in self.arms.items()},
                "camera": f"ros2:{ns}/left/image_raw/compressed,{ns}/right/image_raw/compressed"}

    def start(self) -> None:
        """Join the graph (one participant), start every arm's threads and the camera's."""
        self.endoscope.truth = open_truth(self.truth_path, scene_truth_header(self.names))
        self.participant = dp = open_participant()
        self.endoscope.join(dp)
        for a in self.arms.values():
            a.join(dp)
        self._camera = threading.Thread(target=self.endoscope.run, args=(self._stop,), name="ros2-scene-lab-camera",
                                        daemon=True)
        self._camera.start()

    def stop(self) -> None:
        """Stop every thread, hold and disable every arm, leave the graph, close the truth file."""
        self._stop.set()
        if self._camera is not None:
            self._camera.join(5.0)
            self._camera = None
        for a in self.arms.values():
            a.leave()
        self.participant = None
        if self.endoscope.truth is not None:
            self.endoscope.truth.close()
            self.endoscope.truth = None

    def __enter__(self) -> Ros2SceneLab:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
