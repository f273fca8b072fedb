"""Every shipped arm (configs/robots/*.yaml) runs the cube on the simulated bench with its own
plant file: a short walk with fast settings (the truth-noise sensor) closes the loop
(closed-loop error below the open loop's), and the run's log and result name the arm's joints;
a short walk with vision in the loop (the default sensor) meets issue 28's error targets."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from wristmark.models.arm_spec import ArmSpec, shipped_robot_files
from wristmark.models.errors import ConfigError
from wristmark.sim.experiments import run_cube
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.setup import load_setup

ARMS = shipped_robot_files()


@pytest.mark.slow
@pytest.mark.parametrize("robot", ARMS, ids=[p.stem for p in ARMS])
def test_a_short_cube_closes_the_loop(robot: Path, tmp_path: Path) -> None:
    setup = load_setup(robot=robot)
    assert isinstance(setup.params, ArmSpec)
    rig = dataclasses.replace(setup.rig, sensor="truth-noise", settle_time=0.5)
    res = run_cube(setup.with_changes(rig=rig), tmp_path, progress=False, duration=8.0)
    assert not res["closed_loop"]["stopped"]
    assert res["closed_loop"]["mean_mm"] < res["open_loop"]["mean_mm"]
    assert res["arm"]["configuration"] == list(setup.params.names)
    assert res["arm"]["actuators"] == list(setup.params.actuator_names)
    with open(tmp_path / "log.csv", newline="") as f:
        header = next(csv.reader(f))
    assert [c for c in header if c.startswith("psi_cmd_")] == [f"psi_cmd_{n}" for n in setup.params.names]


# Vision in the loop (rendered 1080p pairs, the tracker, the optical tracker's errors) for each
# shipped arm that is not the paper's (which `make run` walks in full), an 8 s cube after a 0.5 s
# settle: ~30 s an arm on the shared 2-core machine. Measured 2026-12-03 (simulated clock, so
# independent of the load): closed loop mean / max tendon3 0.187 / 0.658 mm, single_tendon
# 0.162 / 0.422 mm, planar 0.150 / 0.605 mm, against the open loop's 1.24 / 0.93 / 1.34 mm mean.
# The bounds are issue 28's targets for the full cube (0.3 mm mean, 1.0 mm max): 1.6 x and 1.5 x
# the worst arm's, room for the controller's tuning to move, not for the loop to fail (a lost
# marker stops the run; an open loop is 6-9 x the mean).
VISION_ARMS = [p for p in ARMS if p.stem in ("tendon3", "single_tendon", "planar")]


@pytest.mark.slow
@pytest.mark.parametrize("robot", VISION_ARMS, ids=[p.stem for p in VISION_ARMS])
def test_a_short_cube_with_vision_in_the_loop_converges(robot: Path, tmp_path: Path) -> None:
    setup = load_setup(robot=robot)
    assert setup.rig.sensor == "vision"  # the default: rendered pairs, tracked
    rig = dataclasses.replace(setup.rig, settle_time=0.5)
    res = run_cube(setup.with_changes(rig=rig), tmp_path, progress=False, duration=8.0)
    c, o = res["closed_loop"], res["open_loop"]
    print(f"\n{robot.stem}: open {o['mean_mm']:.3f} / {o['max_mm']:.3f} mm, closed {c['mean_mm']:.3f} / "
          f"{c['max_mm']:.3f} mm (vision in the loop)")
    assert not c["stopped"] and c["lost"] == 0 and c["cycles"] >= 130
    assert c["mean_mm"] < 0.3 and c["max_mm"] < 1.0
    assert c["mean_mm"] < 0.25 * o["mean_mm"]


def test_each_shipped_arm_has_its_plant_file() -> None:
    for robot in ARMS:
        if robot.stem == "paper":
            continue  # the paper arm keeps configs/plant.yaml
        setup = load_setup(robot=robot)
        assert setup.sources["plant"].endswith(f"{robot.stem}_plant.yaml")


def test_a_plant_file_sized_for_another_arm_is_refused_naming_the_key(tmp_path: Path) -> None:
    bad = tmp_path / "plant.yaml"
    bad.write_text("bend_gain: [0.98, 0.95]\n")
    with pytest.raises(ConfigError, match=r"'bend_gain' must have 3 entries \(one per segment of the arm\), got 2"):
        load_setup(robot=[p for p in ARMS if p.stem == "tendon3"][0], plant=bad)
    with pytest.raises(ConfigError, match=r"'backlash' must have 10 entries \(one per actuator of the arm\)"):
        PlantParams(backlash=(0.0, 0.0)).for_arm(3, 10)


def test_the_v1_actuator_box_refuses_an_arm_of_another_actuator_count() -> None:
    from wristmark.rig.link.actuator_driver import check_protocol_arm

    setup = load_setup(robot=[p for p in ARMS if p.stem == "tendon3"][0])
    with pytest.raises(ConfigError, match=r"protocol v1, which carries 6 actuators; this arm has 10 .*servo --direct"):
        check_protocol_arm(setup.params)


@pytest.mark.parametrize("robot", ARMS, ids=[p.stem for p in ARMS])
def test_the_camera_frames_each_arm_as_close_as_the_reference(robot: Path) -> None:
    """camera_for_arm backs off only as far as the image's edges need (per side): the arm's
    markers over the cube reach no nearer to them than the reference arm's do, and sit no more
    than 20 % deeper (planar was once framed ~45 % deeper, its marker too small to track)."""
    from wristmark.models.robot_params import RobotParams
    from wristmark.sim.setup import _cube_markers, _image_fill

    setup, ref = load_setup(robot=robot), load_setup()
    W, W_ref = (np.asarray(s.camera.T_world_left, float) for s in (setup, ref))
    pts, ref_pts = _cube_markers(setup.params), _cube_markers(RobotParams().with_marker(ref.marker))
    assert _image_fill(setup.camera, pts, W) <= _image_fill(ref.camera, ref_pts, W_ref) + 1e-9

    def depth(P: np.ndarray, T: np.ndarray) -> float:
        inv = np.linalg.inv(T)
        return float(np.mean(P @ inv[2, :3] + inv[2, 3]))

    assert depth(pts, W) <= 1.2 * depth(ref_pts, W_ref)


def test_the_planar_marker_is_tracked_where_the_cube_once_lost_it() -> None:
    """The pose at which the planar arm's closed-loop cube stopped (marker lost at 10.5 s: the
    pitch segment near its limit, the camera framed too far) is tracked."""
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.sim.render.settings import noise_preset
    from wristmark.sim.render.stereo_renderer import StereoRenderer
    from wristmark.sim.setup import make_plant

    setup = load_setup(robot=next(p for p in ARMS if p.stem == "planar"))
    shape = make_plant(setup, np.array([0.091, 0.071, 1.504, -0.045])).true_shape()
    pair = StereoRenderer(setup.render_camera, setup.marker, noise_preset("default"), seed=0).render(shape)
    res = MarkerTracker(setup.tracking_camera, setup.marker).track(pair.left, pair.right)
    assert res.ok, res.doubt


@pytest.mark.parametrize("robot", ARMS, ids=[p.stem for p in ARMS])
def test_the_cube_lies_inside_each_arms_reach(robot: Path) -> None:
    """workspace_centre moves the cube into the arm's nominal reach (planar's +x corners were
    2.1 mm beyond its pitch segment's limit around the home tip); an arm that reaches the cube
    around its home tip keeps it."""
    from wristmark.models.arm_spec import home_psi
    from wristmark.models.ik import solve_tip_ik
    from wristmark.models.kinematics import tip_position
    from wristmark.rig.targets.trajectories import CUBE_SIZE, workspace_centre

    arm = load_setup(robot=robot).params
    q0 = home_psi(arm)
    centre = workspace_centre(arm)
    for corner in np.array(np.meshgrid([-0.5, 0.5], [-0.5, 0.5], [-0.5, 0.5])).reshape(3, -1).T:
        target = centre + corner * np.asarray(CUBE_SIZE)
        assert np.linalg.norm(tip_position(arm, solve_tip_ik(arm, target, q0).psi) - target) < 1e-6
    if robot.stem in ("paper", "tendon3", "single_tendon"):
        assert np.array_equal(centre, tip_position(arm, q0))


def test_the_planar_arm_walks_the_cube_without_drifting_along_its_null_space() -> None:
    """The qp controller on a 4-joint arm under a position task (one spare joint): nominal
    kinematics, the full cube walk; the arm comes back to the start corner in about the
    configuration it left it in, the yaw segment never far bent (it once ran to 1 rad and tilted
    the marker out of view)."""
    from wristmark.models.arm_spec import home_psi
    from wristmark.models.ik import solve_tip_ik
    from wristmark.models.kinematics import tip_position
    from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, cube_trajectory, workspace_centre
    from wristmark.solvers.controller_registry import make_controller

    setup = load_setup(robot=next(p for p in ARMS if p.stem == "planar"))
    arm, dt = setup.params, 0.06
    ctrl = make_controller(arm, dataclasses.replace(setup.controller, backlash_compensation=False))
    traj = cube_trajectory(workspace_centre(arm), CUBE_SIZE, CUBE_SPEED)
    psi = solve_tip_ik(arm, traj.sample(0.0)[0], home_psi(arm)).psi
    start, yaw = psi.copy(), []
    for t in np.arange(dt, traj.duration + dt, dt):
        p, v = traj.sample(min(t, traj.duration))
        psi = ctrl.step(psi, tip_position(arm, psi), p, v, dt).psi_next
        yaw.append(abs(psi[3]))
    assert max(yaw) < 0.6
    assert np.max(np.abs(psi - start)) < 0.25  # without the pull: phi +1.5 rad
