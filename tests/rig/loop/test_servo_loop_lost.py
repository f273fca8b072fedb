"""The servo loop when the marker is lost, with rig ``open_loop_on_lost`` (docs/identification.md):
it walks on along the target open loop for the time set, then holds; its counters say how many
cycles it walked so. Off (the default) it holds at once."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.config_files import CONFIG_DIR
from wristmark.rig.loop.tip_sensors import TipMeasurement, TipSensor
from wristmark.rig.recording.run_log import RunLog
from wristmark.rig.targets.orientation_path import start_configuration
from wristmark.rig.targets.trajectories import Trajectory, workspace_centre
from wristmark.sim.setup import load_setup, make_direct_loop


class Blindfold:
    """A sensor that sees nothing between ``t0`` and ``t1`` [s] of the frames' clock."""

    def __init__(self, inner: TipSensor, t0: float, t1: float) -> None:
        self.inner, self.t0, self.t1 = inner, t0, t1

    def measure(self, frame: StereoFrame, axis_hint_world: np.ndarray | None = None) -> TipMeasurement:
        if self.t0 <= frame.t_capture < self.t1:
            return TipMeasurement(False, None, reason="marker not found", t_capture=frame.t_capture)
        return self.inner.measure(frame, axis_hint_world)


def blind_walk(**rig_changes: Any) -> tuple[Any, RunLog, float]:
    """A 6 s line walked closed loop (truth-noise sensor, the true plant's errors known to the
    loop as its model, the rig changed by ``rig_changes``), blind for 0.6 s in its middle: the
    run's stats, its log and the closed loop's start [s]."""
    setup = load_setup(plant=CONFIG_DIR / "plant_unseen.yaml")
    rig = dataclasses.replace(setup.rig, sensor="truth-noise", **rig_changes)
    setup = setup.with_changes(rig=rig, model=setup.plant)
    c = workspace_centre(setup.params)
    traj = Trajectory.from_waypoints(np.array([c - [0.015, 0, 0], c + [0.015, 0, 0]]), speed=0.005)
    loop = make_direct_loop(setup, start_configuration(setup.params, traj.sample(0.0)[0]), closed_loop=True)
    t_start = loop.t + setup.rig.settle_time
    assert loop.sensor is not None
    loop.sensor = Blindfold(loop.sensor, t_start + 3.0, t_start + 3.6)
    log = RunLog()
    stats = loop.run(traj, "closed_loop", True, log, settle=setup.rig.settle_time)
    return stats, log, t_start


def walk(open_loop_on_lost: float) -> tuple[int, float, float]:
    """:func:`blind_walk` without the lost-marker dither ("held" means the arm holds still; the
    dither: test_lost_dither.py): cycles walked open loop, the largest tip error [m] while blind,
    and the tip's travel while blind [m]."""
    stats, log, t_start = blind_walk(open_loop_on_lost=open_loop_on_lost, lost_dither=0.0)
    blind = [r for r in log.phase("closed_loop") if t_start + 3.06 <= r.t < t_start + 3.6]
    err = max(float(np.linalg.norm(np.subtract(r.p_true, r.p_des))) for r in blind)
    travel = float(np.linalg.norm(np.subtract(blind[-1].p_true, blind[0].p_true)))
    return stats.open_on_lost, err, travel


@pytest.mark.slow
def test_walks_on_open_loop_for_the_time_set_then_holds() -> None:
    held = walk(0.0)
    walked = walk(0.3)
    assert held[0] == 0 and walked[0] == 5  # 0.3 s of 60 ms cycles
    assert walked[2] > held[2] + 0.001  # the arm went on along the line while blind ...
    assert walked[1] < held[1]  # ... and so stayed nearer the target


@pytest.mark.slow
def test_no_dither_while_walking_open_loop() -> None:
    """The lost-marker dither moves an arm that holds; while the loop walks on open loop it
    does not fire (it would pull the command back to where the walk began)."""
    stats, _, _ = blind_walk(open_loop_on_lost=0.3, lost_dither=0.001, lost_dither_after=1)
    # 0.6 s blind = 10 lost cycles: 5 walked open loop, then the arm holds and dithers (5 cycles)
    assert stats.open_on_lost == 5
    assert 1 <= stats.dithers <= 5


@pytest.mark.slow
def test_the_log_says_which_cycles_walked_open_loop(tmp_path: Path) -> None:
    """log.csv's ``open_on_lost``: 1 on exactly the cycles that walked on blind, the first five
    lost ones, 0 on every other."""
    from wristmark.rig.recording.run_log import read_log_csv

    stats, log, _ = blind_walk(open_loop_on_lost=0.3, lost_dither=0.0)
    log.write_csv(tmp_path / "log.csv")
    table = read_log_csv(tmp_path / "log.csv")
    flags = np.asarray(table["open_on_lost"], float)
    lost = np.asarray(table["meas_ok"], float) == 0
    assert flags.sum() == stats.open_on_lost == 5
    assert np.all(lost[flags == 1])
    first_lost = int(np.argmax(lost & (np.asarray(table["phase"]) == "closed_loop")))
    assert np.all(flags[first_lost:first_lost + 5] == 1)
