"""Everything a simulated-bench run needs, loaded and validated in one place, and the pieces
of the bench wired for the servo loop: the true arm, its rendered frames (or the truth-noise
option), the tip sensor and the ground-truth observer."""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.arm_spec import Arm, ArmSpec, arm_size, home_psi, robot_file_format
from wristmark.models.config_files import CONFIG_DIR, default_config
from wristmark.models.config_io import to_mapping
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.marker import MarkerModel
from wristmark.models.plant_interface import ActuatedArm
from wristmark.models.robot_params import RobotParams
from wristmark.rig.link.actuator_link import ActuatorLink, DirectLink
from wristmark.rig.loop.frame_feed import FrameFeed, SynchronousFeed
from wristmark.rig.loop.loop_setup import LoopSetup, config_paths, load_loop_setup
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.loop.tip_sensors import TipSensor, VisionTipSensor
from wristmark.sim.optical_tracker import OpticalTracker
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.render.rendered_source import RenderedStereoSource
from wristmark.sim.truth import SimulatedTruth
from wristmark.sim.truth_sensor import NoisyTruthSensor, TruthClockSource
from wristmark.solvers.controller_registry import make_controller

Array = NDArray[np.float64]
__all__ = ["CONFIG_DIR", "SimSetup", "default_config", "load_setup", "make_measurement", "make_plant",
           "make_truth", "make_direct_loop"]


@dataclass
class SimSetup(LoopSetup):
    """A :class:`rig.loop.loop_setup.LoopSetup` plus the plant file of the simulated true arm."""

    plant: PlantParams = field(default_factory=PlantParams)

    @property
    def true_camera(self) -> StereoCamera:
        """Where the simulated endoscope truly is: the calibration's world_T_left @ T(camera_offset)."""
        if not any(self.plant.camera_offset) or self.camera.T_world_left is None:
            return self.camera
        W = np.asarray(self.camera.T_world_left, float) @ self.plant.camera_offset_transform()
        return dataclasses.replace(self.camera, T_world_left=W)

    @property
    def render_camera(self) -> StereoCamera:
        """The true camera (renders the images) at the rig's image scale."""
        return self._scaled(self.true_camera)

    def describe(self) -> dict[str, Any]:
        """Everything as plain data for config.json."""
        out = {**super().describe(), "plant": to_mapping(self.plant)}
        if self.model is not None:
            out["model"] = to_mapping(self.model)
        return out


def load_setup(
    robot: str | Path | None = None,
    marker: str | Path | None = None,
    camera: str | Path | None = None,
    plant: str | Path | None = None,
    rig: str | Path | None = None,
    controller: str | Path | None = None,
) -> SimSetup:
    """Load every configuration (None -> the file in configs/), validated."""
    base = load_loop_setup(robot=robot, marker=marker, camera=camera, rig=rig, controller=controller)
    plant_path = Path(plant) if plant else arm_plant_file(robot) or config_paths(plant=plant)["plant"]
    n_seg = len(base.params.segments) if isinstance(base.params, ArmSpec) else 2
    the_plant = PlantParams.load(plant_path).for_arm(n_seg, arm_size(base.params)[1], str(plant_path))
    cam = base.camera if camera is not None else camera_for_arm(base.camera, base.params, base.marker)
    return SimSetup(params=base.params, marker=base.marker, camera=cam, rig=base.rig,
                    controller=base.controller, sources={**base.sources, "plant": str(plant_path)},
                    plant=the_plant)


def arm_plant_file(robot: str | Path | None) -> Path | None:
    """The plant file shipped beside a format-2 robot file (``<name>_plant.yaml``, e.g.
    configs/robots/tendon3_plant.yaml), if there is one: the default plant of that arm."""
    if robot is None or robot_file_format(robot) != 2:
        return None
    p = Path(robot).with_name(Path(robot).stem + "_plant.yaml")
    return p if p.is_file() else None


_MARGIN = 1.1


def camera_for_arm(camera: StereoCamera, arm: Arm, marker: MarkerModel) -> StereoCamera:
    """The default endoscope (configs/camera.yaml, placed for the reference arm: the marker over
    the experiments' cube in view, its axis across the image) moved to frame ``arm``'s workspace:
    translated so that the centre of the arm's marker positions over the cube's corners (nominal
    IK from home) sits where the reference arm's does, rolled about its optical axis so that the
    arm's marker axis at home crosses the image as the reference arm's does, then backed off
    along the optical axis (with 10 % margin) until the markers reach no nearer to the image's
    edges than the reference arm's do (``_image_fill``; side by side, so a spread along the
    image's width, which the reference arm leaves mostly free, does not push the camera away).
    The reference arm (flat file) keeps the file's pose."""
    if not isinstance(arm, ArmSpec) or camera.T_world_left is None:
        return camera
    W = np.array(camera.T_world_left, float)
    ref = RobotParams().with_marker(marker)
    ref_pts = _cube_markers(ref)
    pts = _cube_markers(arm)
    if np.allclose(pts, ref_pts, rtol=0.0, atol=1e-9):  # the reference arm in format 2: the file's pose
        return camera
    W[:3, 3] += pts.mean(0) - ref_pts.mean(0)
    # rolled about its optical axis so that the arm's marker axis at home lies in the image as
    # the reference arm's does (across the image; the cube's motion stays side-on)
    a_ref = W[:3, :3].T @ forward_kinematics(ref, home_psi(ref)).T_world_marker[:3, 2]
    a_arm = W[:3, :3].T @ forward_kinematics(arm, home_psi(arm)).T_world_marker[:3, 2]
    roll = math.atan2(a_arm[1], a_arm[0]) - math.atan2(a_ref[1], a_ref[0])
    c, s_ = math.cos(roll), math.sin(roll)
    W[:3, :3] = W[:3, :3] @ np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    depth = float(np.linalg.inv(W)[:3, :3][2] @ pts.mean(0) + np.linalg.inv(W)[2, 3])
    ref_fill = _image_fill(camera, ref_pts, np.asarray(camera.T_world_left, float))
    ratio = max(1.0, _image_fill(camera, pts, W) / ref_fill)
    W[:3, 3] -= W[:3, 2] * depth * (ratio * _MARGIN - 1.0)
    return dataclasses.replace(camera, T_world_left=W)


def _image_fill(camera: StereoCamera, P: Array, T_world_left: Array) -> float:
    """How far the points ``P`` (N,3) in {w} [m] reach towards the left image's edges, seen from
    ``T_world_left``: the largest of their (undistorted) offsets from the principal point over
    the image's extent on that side (1: at the edge; per side, so a spread along the image's long
    side counts against its width)."""
    inv = np.linalg.inv(T_world_left)
    c = P @ inv[:3, :3].T + inv[:3, 3]
    xy = c[:, :2] / c[:, 2:]
    K = np.asarray(camera.left.K, float)
    w, h = camera.image_size
    f, cc, size = np.array([K[0, 0], K[1, 1]]), np.array([K[0, 2], K[1, 2]]), np.array([w - 1.0, h - 1.0])
    lo, hi = -cc / f, (size - cc) / f  # the image's normalised extent on each side (< 0, > 0)
    return float(max(np.max(xy.min(0) / lo), np.max(xy.max(0) / hi)))


def _cube_markers(arm: Arm) -> Array:
    """Marker centres in {w} [m] with the tip at the paper cube's 8 corners (:func:`cube_markers`)."""
    from wristmark.rig.targets.trajectories import CUBE_SIZE

    return cube_markers(arm, CUBE_SIZE)


def cube_markers(arm: Arm, size: tuple[float, float, float]) -> Array:
    """Marker centres in the arm's {w} [m] with the tip at the 8 corners of a cube of edges
    ``size`` [m] around the arm's workspace centre (``workspace_centre``: inside the arm's reach;
    nominal IK from home)."""
    from wristmark.models.ik import solve_tip_ik
    from wristmark.rig.targets.trajectories import workspace_centre

    q0 = home_psi(arm)
    centre = workspace_centre(arm, size)
    out = []
    for corner in itertools.product((-0.5, 0.5), repeat=3):
        q = solve_tip_ik(arm, centre + np.multiply(corner, size), q0).psi
        out.append(forward_kinematics(arm, q).T_world_marker[:3, 3])
    return np.array(out)


def make_measurement(setup: SimSetup, arm: ActuatedArm, clock: Callable[[], float],
                     seed: int) -> tuple[FrameFeed, TipSensor]:
    """The frames and the tip sensor the rig config asks for: rendered frames of ``arm`` stamped
    with ``clock`` and the marker tracker (vision, the default), or the truth-noise option."""
    if setup.rig.sensor == "truth-noise":
        return SynchronousFeed(TruthClockSource(clock)), NoisyTruthSensor(arm, setup.rig.truth_noise_rms, seed)
    source = RenderedStereoSource(arm, setup.render_camera, setup.marker, clock, noise=setup.rig.render_noise,
                                  seed=seed, age=setup.rig.frame_age,
                                  gloss=(setup.rig.sleeve_specular, setup.rig.sleeve_roughness))
    return SynchronousFeed(source), VisionTipSensor(setup.tracking_camera, setup.marker,
                                                    magnify=setup.rig.tracker_magnify)


def make_truth(setup: SimSetup, arm: ActuatedArm, seed: int) -> SimulatedTruth:
    """The ground-truth observer of ``arm`` (optical tracker seeded ``seed + 7``)."""
    return SimulatedTruth(arm, OpticalTracker(setup.rig.tracker_rms, seed=seed + 7))


def make_plant(setup: SimSetup, psi0: Array) -> TruePlant:
    """A fresh simulated true arm resting at configuration psi0 (commanded); it remembers its
    past for the rig's ``frame_age`` (and a cycle more)."""
    history = setup.rig.frame_age + setup.rig.control_dt if setup.rig.frame_age > 0 else 0.0
    return TruePlant(setup.params, setup.plant, psi0=np.asarray(psi0, float), dt_internal=setup.rig.plant_dt,
                     history=history)


def make_direct_loop(setup: SimSetup, psi0: Array, closed_loop: bool, seed: int = 0) -> ServoLoop:
    """An in-process servo loop on a fresh plant, started (settled) at psi0."""
    plant = make_plant(setup, psi0)
    link: ActuatorLink = DirectLink(plant)
    frames, sensor = make_measurement(setup, plant, lambda: link.time, seed) if closed_loop else (None, None)
    controller = make_controller(setup.params, setup.controller) if closed_loop else None
    rig = setup.rig
    if setup.model is not None:  # --model: command the identified arm's inverse (docs/identification.md)
        from wristmark.rig.loop.model_loop import model_rig, use_model

        link = use_model(link, setup.params, setup.model, controller, setup.rig.control_dt)
        rig = model_rig(rig, setup.model)
    loop = ServoLoop(setup.params, rig, link, frames=frames, sensor=sensor, truth=make_truth(setup, plant, seed),
                     controller=controller)
    loop.start_at(psi0)
    return loop
