"""What a servo loop needs, on hardware or on the simulated bench, loaded and validated in one
place: the robot, the marker, the stereo calibration, the loop and the controller.

:class:`sim.setup.SimSetup` extends :class:`LoopSetup` with the simulated true arm's plant file;
the hardware path (``wristmark servo --serial --camera``) needs only this module.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.models.arm_spec import Arm, load_loop_arm
from wristmark.models.config_files import default_config
from wristmark.models.config_io import load_layered, to_mapping
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.plant_params import PlantParams
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.solvers.controller import ControllerConfig

Array = NDArray[np.float64]



@dataclass
class LoopSetup:
    """Robot, marker, stereo calibration, loop and controller configuration of a servo run."""

    params: Arm
    marker: MarkerModel
    camera: StereoCamera
    rig: RigConfig
    controller: ControllerConfig
    sources: dict[str, str] = field(default_factory=dict)
    registration: Array | None = None
    model: PlantParams | None = None  # --model: the identified arm the loop commands through (rig/loop/model_loop.py)

    @property
    def host_camera(self) -> StereoCamera:
        """What the host believes: the calibration, with world_T_left from the registration if given."""
        if self.registration is None:
            return self.camera
        return dataclasses.replace(self.camera, T_world_left=np.asarray(self.registration, float))

    def _scaled(self, cam: StereoCamera) -> StereoCamera:
        return cam if self.rig.image_scale == 1.0 else scaled_stereo_camera(cam, self.rig.image_scale)

    @property
    def scaled_camera(self) -> StereoCamera:
        """The host's camera (tracks the marker, maps {ll} to {w}) at the rig's image scale (a
        camera delivering ``image_scale`` times the calibrated resolution)."""
        return self._scaled(self.host_camera)

    @property
    def tracking_camera(self) -> StereoCamera:
        """Alias of :attr:`scaled_camera`: the camera the tracker uses."""
        return self.scaled_camera

    def with_changes(self, **changes: Any) -> Any:
        """Copy with some members replaced (e.g. rig=...)."""
        return dataclasses.replace(self, **changes)

    def describe(self) -> dict[str, Any]:
        """Everything as plain data for config.json."""
        from wristmark.cvs.calibration.load import calibration_mapping

        return {
            "sources": self.sources,
            "robot": to_mapping(self.params),
            "marker": to_mapping(self.marker),
            "rig": to_mapping(self.rig),
            "controller": to_mapping(self.controller),
            "camera": calibration_mapping(self.camera),
            "registration_world_T_left": None if self.registration is None else np.asarray(self.registration).tolist(),
        }


def config_paths(**given: str | Path | None) -> dict[str, Path]:
    """Each named configuration file (robot, marker, camera, rig, controller, ...): the given
    path, or configs/<name>.yaml."""
    return {k: Path(v) if v else default_config(f"{k}.yaml") for k, v in given.items()}


def load_loop_setup(robot: str | Path | None = None, marker: str | Path | None = None,
                    camera: str | Path | None = None, rig: str | Path | None = None,
                    controller: str | Path | None = None, require_world: bool = True) -> LoopSetup:
    """Load every configuration (None -> the file in configs/), validated; the calibration must
    place the camera in {w} (``world_T_left``) unless ``require_world`` is False (the caller
    then sets the registration)."""
    from wristmark.cvs.calibration.load import load_calibration

    paths = config_paths(robot=robot, marker=marker, camera=camera, rig=rig, controller=controller)
    cam = load_calibration(paths["camera"])
    if cam.T_world_left is None and require_world:
        raise ConfigError(f"{paths['camera']}: the servo loop needs 'world_T_left' (camera pose in {{w}})")
    the_marker = MarkerModel.load(paths["marker"])
    loop = RigConfig.load(paths["rig"])
    return LoopSetup(
        params=load_loop_arm(paths["robot"], the_marker),
        marker=the_marker,
        camera=cam,
        rig=loop,
        controller=controller_with_cycle(ControllerConfig.load(paths["controller"]), loop, paths),
        sources={k: str(v) for k, v in paths.items()},
    )


def controller_with_cycle(controller: ControllerConfig, rig: RigConfig, paths: dict[str, Path]) -> ControllerConfig:
    """The controller running at the loop's cycle: the servo cycle [s] is defined once, by the rig
    file's ``control_dt``. A controller file that states a different ``dt`` is refused, naming it."""
    if "dt" in load_layered(paths["controller"], "controller") and controller.dt != rig.control_dt:
        raise ConfigError(f"{paths['controller']}: 'dt' ({controller.dt} s) disagrees with 'control_dt' "
                          f"({rig.control_dt} s) of {paths['rig']}: the cycle time belongs to the loop; set "
                          f"'dt' to {rig.control_dt} or remove it from {paths['controller']}")
    return dataclasses.replace(controller, dt=rig.control_dt)
