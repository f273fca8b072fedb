"""Your own trajectory walked in process (sim.trajectory_run.run_trajectory): the experiments'
loop, its errors and log returned, nothing written; a path out of reach refused before it runs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from wristmark.models.errors import ConfigError
from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, Trajectory, cube_trajectory, workspace_centre
from wristmark.sim import TrajectoryRun, run_trajectory
from wristmark.sim.experiments import run_cube
from wristmark.sim.setup import load_setup

SETUP = load_setup()
FAST = SETUP.with_changes(rig=dataclasses.replace(SETUP.rig, sensor="truth-noise"))


def _circle(radius: float, step_deg: float = 10.0) -> Trajectory:
    theta = np.deg2rad(np.arange(0.0, 360.0 + step_deg / 2, step_deg))
    c = workspace_centre(SETUP.params)
    pts = c + radius * np.column_stack([np.cos(theta) - 1.0, np.zeros_like(theta), np.sin(theta)])
    return Trajectory.from_waypoints(pts, 0.01)


def test_a_circle_closed_loop_returns_the_log_and_the_errors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    path = _circle(0.003)
    run = run_trajectory(FAST, path, seed=4)
    assert isinstance(run, TrajectoryRun) and run.closed_loop and run.phase == "closed_loop"
    assert run.stopped == "" and run.stats.lost == 0
    walk = run.records
    assert len(walk) == int(np.floor(path.duration / FAST.rig.control_dt)) + 1 == run.errors.n
    assert {r.phase for r in run.log.records} <= {"closed_loop", "closed_loop:settle", "closed_loop:probe"}
    assert [r.phase for r in run.log.records][-len(walk):] == ["closed_loop"] * len(walk)  # settle first
    assert 0 < run.errors.mean_mm < 1.0 and run.errors.max_mm < 2.0  # tracker vs desired [mm]
    assert run.true_errors.mean_mm < 1.0
    assert run.summary["mean_mm"] == run.errors.mean_mm and run.summary["cycles"] == run.errors.n
    open_loop = run_trajectory(FAST, path, closed_loop=False, seed=4)
    assert open_loop.phase == "open_loop" and open_loop.errors.mean_mm > 2 * run.errors.mean_mm
    assert not list(tmp_path.iterdir())  # nothing written


def test_the_cube_experiment_walks_through_the_same_function(tmp_path: Path) -> None:
    """run_cube's phases are run_trajectory's walks: the same numbers for the same path and seed."""
    traj = cube_trajectory(workspace_centre(FAST.params), CUBE_SIZE, CUBE_SPEED).truncated(2.0)
    res = run_cube(FAST, tmp_path, progress=False, seed=3, duration=2.0)
    for phase, closed in (("closed_loop", True), ("open_loop", False)):
        run = run_trajectory(FAST, traj, closed_loop=closed, seed=3)
        assert run.errors.mean_mm == res[phase]["mean_mm"] and run.errors.max_mm == res[phase]["max_mm"]


def test_a_waypoint_out_of_reach_is_refused_before_anything_runs() -> None:
    c = workspace_centre(SETUP.params)
    path = Trajectory.from_waypoints([c, c + [0.0, 0.0, 0.5]], 0.01)
    with pytest.raises(ConfigError, match=r"waypoint 1, \[.*\] mm is out of reach of the arm"):
        run_trajectory(SETUP, path)
