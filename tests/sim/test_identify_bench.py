"""Identification on the simulated bench (sim/identify_bench.py): the fit of a short excitation
(truth-noise sensor: fast) recovers the plant, and the identified model (--model) cuts the
open-loop cube error to a fraction of the nominal model's."""

from __future__ import annotations

import dataclasses

import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.rig.recording.run_log import RunLog
from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, cube_trajectory, workspace_centre
from wristmark.sim.identify_bench import bench_plan, excite_on_bench
from wristmark.sim.setup import load_setup
from wristmark.sim.trajectory_run import walk_trajectory
from wristmark.solvers.identification import identify


@pytest.mark.slow
def test_the_identified_model_halves_the_open_loop_error() -> None:
    setup = load_setup(plant=CONFIG_DIR / "plant_unseen.yaml")
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"))
    data = excite_on_bench(setup, bench_plan(setup, 16))
    fit = identify(setup.params, data, setup.controller.play_max_for(setup.params))
    assert fit.plant.bend_gain == pytest.approx(setup.plant.bend_gain, abs=0.01)
    assert fit.plant.actuator_tau == pytest.approx(setup.plant.actuator_tau, rel=0.05)
    traj = cube_trajectory(workspace_centre(setup.params), CUBE_SIZE, CUBE_SPEED).truncated(8.0)
    nominal = walk_trajectory(setup, traj, False, RunLog()).true_errors
    modelled = walk_trajectory(setup.with_changes(model=fit.plant), traj, False, RunLog()).true_errors
    assert nominal.mean_mm > 3.0
    assert modelled.mean_mm < 0.5 * nominal.mean_mm
    assert modelled.max_mm < nominal.max_mm
