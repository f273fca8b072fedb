"""The virtual lab's dense truth: the true tip logged every few ms of the actuator box's clock,
paired exactly with the frames' truth; errors evaluated at the cycles' nominal instants."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.rig.link.test_serial_link import PARAMS, PLANT
from wristmark.models.robot_params import HOME_PSI
from wristmark.rig.recording.run_log import CycleRecord, RunLog
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.dense_truth import DenseTruthArm
from wristmark.sim.locked_arm import LockedArm
from wristmark.sim.plant import TruePlant
from wristmark.sim.virtual_lab import read_truth_csv, true_tip_errors


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_the_dense_truth_follows_the_box_clock_and_matches_the_arm(tmp_path: Path) -> None:
    clock = _Clock()
    arm = DenseTruthArm(LockedArm(TruePlant(PARAMS, PLANT, psi0=np.asarray(HOME_PSI, float))), min_interval=0.004)
    emu = ActuatorEmulator(arm, PARAMS, clock=clock)
    arm.start(emu.sample_arm()[0], tmp_path / "dense.csv")
    a = arm.measured_actuators()
    arm.command(a + np.array([0.05, 0.002, 0, 0, 0, 0]))  # a step: the tip moves through the lag
    samples = []
    for k in range(40):
        clock.t += 0.0025 if k % 2 else 0.001  # polls 1 and 2.5 ms apart: logged at most every 4 ms
        t, shape = emu.sample_arm()  # what a frame shows at t
        samples.append((t, shape.tip))
    lines = (tmp_path / "dense.csv").read_text().splitlines()
    assert len(lines) == 2  # header and the first row: the box's thread does no file I/O ...
    arm.flush()  # ... the camera thread writes the rows
    assert len((tmp_path / "dense.csv").read_text().splitlines()) == 1 + arm.rows > 10
    arm.close()
    t, tip = read_truth_csv(tmp_path / "dense.csv")
    assert t[0] == pytest.approx(100.0) and len(t) == arm.rows
    assert np.all(np.diff(t) >= 0.004 - 1e-9) and np.diff(t).max() < 0.004 + 0.0026
    assert np.linalg.norm(tip[-1] - tip[0]) > 5e-4  # it moved
    for ts, p in samples:  # the frames' truth lies on the dense one where they coincide in time
        hit = np.flatnonzero(np.abs(t - ts) < 1e-7)
        if hit.size:
            assert np.allclose(tip[hit[0]], p, atol=1e-8)
    assert sum(np.any(np.abs(t - ts) < 1e-7) for ts, _ in samples) >= 10


def _log(tmp_path: Path, t_nominal: np.ndarray, late: float, p_des: np.ndarray) -> Path:
    log = RunLog()
    z = np.zeros(3)
    for tn, pd in zip(t_nominal, p_des, strict=True):
        log.add(CycleRecord(t=float(tn), phase="servo", p_des=pd, p_cmd=z, p_est=None, p_true=z * np.nan,
                            p_trk=z * np.nan, psi_cmd=np.zeros(6), psi_true=np.full(6, np.nan), meas_ok=False,
                            rejected=False, vision_ms=0.0, ctrl_us=0.0, t_wall=float(tn + late)))
    path = tmp_path / "log.csv"
    log.write_csv(path)
    return path


def test_errors_are_evaluated_at_the_nominal_instant_or_at_t_wall(tmp_path: Path) -> None:
    """An arm exactly on a 10 mm/s path: zero error at the cycles' nominal instants; a host whose
    cycles start 5 ms late would show 0.05 mm at t_wall against the earlier desired tip."""
    v = np.array([0.01, 0.0, 0.0])
    t_truth = np.linspace(0.0, 2.0, 501)
    truth = tmp_path / "truth.csv"
    with open(truth, "w") as f:
        f.write("t,tip_x,tip_y,tip_z\n")
        for tt in t_truth:
            x, y, z = v * tt
            f.write(f"{tt:.6f},{x:.9g},{y:.9g},{z:.9g}\n")
    tn = np.arange(0.3, 1.5, 0.06)
    path = _log(tmp_path, tn, 0.005, np.outer(tn, v))
    assert np.allclose(true_tip_errors(path, truth), 0.0, atol=1e-9)
    assert np.allclose(true_tip_errors(path, truth, at="t_wall"), 0.005 * 0.01, atol=1e-9)
