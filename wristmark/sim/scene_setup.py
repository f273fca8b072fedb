"""Everything a run of several arms in one view needs (sim.scene): one :class:`SimSetup` per arm,
each in the arm's own world frame (its camera's ``world_T_left`` is the scene camera's seen from
the arm's base), and the scene camera in the scene's {w}.

The camera: the scene's ``camera`` file as it is, or by default configs/camera.yaml backed off
along its optical axis (and centred) until every arm's marker over the corners of its cube
reaches no nearer to the image's edges than the reference arm's does over its own cube in the
one-arm bench (sim.setup.camera_for_arm, 10 % margin).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.scene import Scene
from wristmark.sim.setup import SimSetup, _image_fill, cube_markers, load_setup

Array = NDArray[np.float64]
_MARGIN = 1.1

__all__ = ["SceneSetup", "load_scene_setup", "cube_markers", "camera_for_scene"]


@dataclass
class SceneSetup:
    """A scene's arms (name -> their SimSetup, each in its own {w}; the order of the scene file),
    the scene camera (``world_T_left`` in the scene's {w}, unscaled) and the scene."""

    scene: Scene
    arms: dict[str, SimSetup]
    camera: StereoCamera

    @property
    def names(self) -> list[str]:
        """The arms' names in the scene file's order."""
        return list(self.arms)

    @property
    def markers(self) -> list[MarkerModel]:
        """The arms' markers, in order."""
        return [s.marker for s in self.arms.values()]

    def base(self, name: str) -> Array:
        """Pose of arm ``name``'s {w} in the scene's {w} (4x4, [m])."""
        return next(a.base for a in self.scene.arms if a.name == name)

    def scaled(self, camera: StereoCamera) -> StereoCamera:
        """``camera`` at the rig's image scale (every arm shares the rig)."""
        return next(iter(self.arms.values()))._scaled(camera)

    @property
    def render_camera(self) -> StereoCamera:
        """The scene camera at the rig's image scale (renders the frames, tracks every sleeve)."""
        return self.scaled(self.camera)

    def describe(self) -> dict[str, Any]:
        """Plain data for config.json: the scene and each arm's setup."""
        return {"scene": self.scene.source, "clearance_m": self.scene.clearance,
                "clearance_margin_m": self.scene.clearance_margin,
                "cube_size_m": list(self.scene.cube_size),
                "arms": {n: {"base": self.base(n).tolist(), **s.describe()} for n, s in self.arms.items()}}


def camera_for_scene(camera: StereoCamera, points_world: Array, marker: MarkerModel) -> StereoCamera:
    """The calibration's camera moved to frame ``points_world`` (N, 3) in {w} [m]: translated
    across its optical axis to centre them, then backed off along it until they reach no nearer
    to the image's edges than the reference arm's markers over the paper's cube do (10 % margin)."""
    from wristmark.rig.targets.trajectories import CUBE_SIZE

    if camera.T_world_left is None:
        raise ConfigError("the scene's camera needs 'world_T_left' (its pose in the scene's {w})")
    W0 = np.asarray(camera.T_world_left, float)
    ref = cube_markers(RobotParams().with_marker(marker), CUBE_SIZE)
    ref_fill = _image_fill(camera, ref, W0)
    W = W0.copy()
    inv = np.linalg.inv(W0)
    c_ref, c_pts = ref @ inv[:3, :3].T + inv[:3, 3], points_world @ inv[:3, :3].T + inv[:3, 3]
    shift = c_pts.mean(0) - c_ref.mean(0)  # in the camera's axes
    W[:3, 3] += W0[:3, :3] @ np.array([shift[0], shift[1], 0.0])
    depth = float(np.mean(points_world @ np.linalg.inv(W)[:3, :3][2] + np.linalg.inv(W)[2, 3]))
    ratio = max(1.0, _image_fill(camera, points_world, W) / ref_fill)
    if ratio > 1.0:
        W[:3, 3] -= W[:3, 2] * depth * (ratio * _MARGIN - 1.0)
    return dataclasses.replace(camera, T_world_left=W)


def load_scene_setup(scene: Scene | str | Path, rig: str | Path | None = None,
                     controller: str | Path | None = None) -> SceneSetup:
    """Load a scene (file or :class:`Scene`) and every arm's configuration (the rig and
    controller files shared by all arms; None: configs/); validated."""
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.models.config_files import default_config

    sc = scene if isinstance(scene, Scene) else Scene.load(scene)
    setups: dict[str, SimSetup] = {}
    for a in sc.arms:
        setups[a.name] = load_setup(robot=a.robot, marker=a.marker, plant=a.plant, rig=rig, controller=controller)
    first = next(iter(setups.values()))
    cam = load_calibration(sc.camera if sc.camera is not None else default_config("camera.yaml"))
    if sc.camera is None:
        pts = np.vstack([cube_markers(s.params, sc.cube_size) @ sc.arms[i].base[:3, :3].T + sc.arms[i].base[:3, 3]
                         for i, s in enumerate(setups.values())])
        cam = camera_for_scene(cam, pts, first.marker)
    elif cam.T_world_left is None:
        raise ConfigError(f"{sc.camera}: the scene's camera needs 'world_T_left' (its pose in the scene's {{w}})")
    W = np.asarray(cam.T_world_left, float)
    for a in sc.arms:
        setups[a.name] = setups[a.name].with_changes(camera=dataclasses.replace(
            cam, T_world_left=np.linalg.inv(a.base) @ W))
    return SceneSetup(sc, setups, cam)
