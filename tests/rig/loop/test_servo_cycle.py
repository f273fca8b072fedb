"""rig.loop.servo_cycle: the ramp that joins two configurations within the velocity limits, the
phase counters' stop errors, and a cycle's target."""

from __future__ import annotations

import numpy as np

from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.servo_cycle import CameraStalledError, MarkerLostError, PhaseStats, cycle_target, ramp_to
from wristmark.rig.targets.trajectories import Trajectory

PARAMS = RobotParams()
DT = 0.06


def test_ramp_steps_stay_within_the_velocity_limits_and_reach_the_target() -> None:
    start = np.asarray(HOME_PSI, float)
    target = start + np.array([0.3, 0.01, 0.4, 0.5, 0.2, 0.6])
    ramp = ramp_to(PARAMS, start, target, DT)
    path = np.array([start, *ramp, target])
    steps = np.abs(np.diff(path, axis=0))
    assert len(ramp) >= 1
    assert np.all(steps <= np.asarray(PARAMS.max_velocity) * DT + 1e-12)


def test_a_slow_ramp_stays_within_its_fraction_of_the_limits() -> None:
    start = np.asarray(HOME_PSI, float)
    target = start + np.array([0.3, 0.01, 0.4, 0.5, 0.2, 0.6])
    fast, slow = ramp_to(PARAMS, start, target, DT), ramp_to(PARAMS, start, target, DT, speed=0.3)
    steps = np.abs(np.diff(np.array([start, *slow, target]), axis=0))
    assert np.all(steps <= 0.3 * np.asarray(PARAMS.max_velocity) * DT + 1e-12)
    assert len(slow) + 1 >= len(fast) / 0.3  # steps: ceil(x / 0.3) against ceil(x)


def test_ramp_turns_the_bending_planes_the_short_way() -> None:
    start = np.asarray(HOME_PSI, float).copy()
    start[3] = 3.0
    target = start.copy()
    target[3] = -3.0  # 0.28 rad the short way round, 6 rad the long way
    ramp = ramp_to(PARAMS, start, target, DT)
    assert len(ramp) <= 1
    for psi in ramp:
        assert abs(psi[3]) > 3.0


def test_a_stalled_camera_is_a_lost_marker_with_the_phase_counters() -> None:
    stats = PhaseStats(cycles=5, lost=3)
    err = CameraStalledError("no frame", stats)
    assert isinstance(err, MarkerLostError) and err.stats is stats and err.record is None


def test_cycle_target_holds_the_start_while_settling_then_walks_the_path() -> None:
    rig = RigConfig()
    dt = rig.control_dt
    traj = Trajectory(np.array([[0.0, 0.0, 0.1], [0.01, 0.0, 0.1]]), 0.01)  # 1 s along +x at 10 mm/s
    settle = [cycle_target(traj, rig, k, k * dt, 5) for k in range(5)]
    assert all(t.settling and np.allclose(t.p_des, traj.waypoints[0]) for t in settle)
    walk = cycle_target(traj, rig, 5 + 8, 13 * dt, 5)
    assert not walk.settling and np.allclose(walk.p_des, traj.sample(8 * dt)[0])
    assert np.allclose(walk.p_next, traj.sample(9 * dt)[0])  # the open loop aims at the cycle's end
    assert walk.R_des is None  # a path without an orientation
