"""Everything a simulated-bench run needs, loaded and validated in one place."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvs.camera import StereoCamera, scaled_stereo_camera
from cvs.marker import MarkerModel
from models.config_io import to_mapping
from models.errors import ConfigError
from models.robot_params import RobotParams
from rig.actuator_link import DirectLink
from rig.rig_config import RigConfig
from rig.servo_loop import ServoLoop
from rig.tip_sensors import NoisyTruthSensor, TipSensor, VisionTipSensor
from sim.optical_tracker import OpticalTracker
from sim.plant import TruePlant
from sim.plant_params import PlantParams
from solvers.controller import ControllerConfig, make_controller

Array = NDArray[np.float64]
CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"


def default_config(name: str) -> Path:
    """Path of a file in the project's configs/ folder."""
    return CONFIG_DIR / name


@dataclass
class SimSetup:
    """Robot, marker, camera, plant, loop and controller configuration of a simulated run."""

    params: RobotParams
    marker: MarkerModel
    camera: StereoCamera
    plant: PlantParams
    rig: RigConfig
    controller: ControllerConfig
    sources: dict[str, str] = field(default_factory=dict)
    registration: Array | None = None

    @property
    def true_camera(self) -> StereoCamera:
        """Where the simulated endoscope truly is: the calibration's world_T_left @ T(camera_offset)."""
        if not any(self.plant.camera_offset) or self.camera.T_world_left is None:
            return self.camera
        W = np.asarray(self.camera.T_world_left, float) @ self.plant.camera_offset_transform()
        return dataclasses.replace(self.camera, T_world_left=W)

    @property
    def host_camera(self) -> StereoCamera:
        """What the host believes: the calibration, with world_T_left from the registration if given."""
        if self.registration is None:
            return self.camera
        return dataclasses.replace(self.camera, T_world_left=np.asarray(self.registration, float))

    def _scaled(self, cam: StereoCamera) -> StereoCamera:
        return cam if self.rig.image_scale == 1.0 else scaled_stereo_camera(cam, self.rig.image_scale)

    @property
    def render_camera(self) -> StereoCamera:
        """The true camera (renders the images) at the rig's image scale."""
        return self._scaled(self.true_camera)

    @property
    def tracking_camera(self) -> StereoCamera:
        """The host's camera (tracks the marker, maps {ll} to {w}) at the rig's image scale."""
        return self._scaled(self.host_camera)

    def with_changes(self, **changes: Any) -> SimSetup:
        """Copy with some members replaced (e.g. plant=..., rig=...)."""
        return dataclasses.replace(self, **changes)

    def describe(self) -> dict[str, Any]:
        """Everything as plain data for config.json."""
        cam = self.camera
        return {
            "sources": self.sources,
            "robot": to_mapping(self.params),
            "marker": to_mapping(self.marker),
            "plant": to_mapping(self.plant),
            "rig": to_mapping(self.rig),
            "controller": to_mapping(self.controller),
            "camera": {
                "image_size": list(cam.image_size),
                "left": {"K": np.asarray(cam.left.K).tolist(), "dist": np.asarray(cam.left.dist).tolist()},
                "right": {"K": np.asarray(cam.right.K).tolist(), "dist": np.asarray(cam.right.dist).tolist()},
                "R": np.asarray(cam.R).tolist(), "T": np.asarray(cam.T).tolist(),
                "world_T_left": None if cam.T_world_left is None else np.asarray(cam.T_world_left).tolist(),
            },
            "registration_world_T_left": None if self.registration is None else np.asarray(self.registration).tolist(),
        }


def load_setup(
    robot: str | Path | None = None,
    marker: str | Path | None = None,
    camera: str | Path | None = None,
    plant: str | Path | None = None,
    rig: str | Path | None = None,
    controller: str | Path | None = None,
) -> SimSetup:
    """Load every configuration (None -> the file in configs/), validated."""
    from cvs.calibration_io import load_calibration

    paths = {
        "robot": Path(robot) if robot else default_config("robot.yaml"),
        "marker": Path(marker) if marker else default_config("marker.yaml"),
        "camera": Path(camera) if camera else default_config("camera.yaml"),
        "plant": Path(plant) if plant else default_config("plant.yaml"),
        "rig": Path(rig) if rig else default_config("rig.yaml"),
        "controller": Path(controller) if controller else default_config("controller.yaml"),
    }
    cam = load_calibration(paths["camera"])
    if cam.T_world_left is None:
        raise ConfigError(f"{paths['camera']}: the simulated rig needs 'world_T_left' (camera pose in {{w}})")
    return SimSetup(
        params=RobotParams.load(paths["robot"]),
        marker=MarkerModel.load(paths["marker"]),
        camera=cam,
        plant=PlantParams.load(paths["plant"]),
        rig=RigConfig.load(paths["rig"]),
        controller=ControllerConfig.load(paths["controller"]),
        sources={k: str(v) for k, v in paths.items()},
    )


def make_sensor(setup: SimSetup, seed: int) -> TipSensor:
    """The tip sensor the rig config asks for (vision by default)."""
    if setup.rig.sensor == "truth-noise":
        return NoisyTruthSensor(setup.rig.truth_noise_rms, seed)
    return VisionTipSensor(setup.render_camera, setup.marker, setup.rig.render_noise, seed,
                           host_camera=setup.tracking_camera)


def make_plant(setup: SimSetup, psi0: Array) -> TruePlant:
    """A fresh simulated true arm resting at configuration psi0 (commanded)."""
    return TruePlant(setup.params, setup.plant, psi0=np.asarray(psi0, float), dt_internal=setup.rig.plant_dt)


def make_direct_loop(setup: SimSetup, psi0: Array, closed_loop: bool, seed: int = 0) -> ServoLoop:
    """An in-process servo loop on a fresh plant, started (settled) at psi0."""
    plant = make_plant(setup, psi0)
    loop = ServoLoop(
        setup.params, setup.rig, DirectLink(plant), plant,
        OpticalTracker(setup.rig.tracker_rms, seed=seed + 7),
        sensor=make_sensor(setup, seed) if closed_loop else None,
        controller=make_controller(setup.params, setup.controller) if closed_loop else None,
    )
    loop.start_at(psi0)
    return loop
