"""`wristmark servo --orientation`: the tip frame's orientation through the serial loop (the
bench's emulator on a pty, vision on the coded marker), its errors in the result, and the
refusals (the paper's position-only controller)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.robot_params import RobotParams
from wristmark.rig.loop.servo_summary import orientation_errors_of
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.rig.targets.trajectories import Trajectory
from wristmark.sim.plant_params import PlantParams

ROOT = Path(__file__).resolve().parents[3]


def wristmark(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "wristmark", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)


@pytest.mark.slow
def test_servo_holds_the_orientation_through_the_pty(tmp_path: Path) -> None:
    res_file = tmp_path / "res.json"
    r = wristmark("servo", "--orientation", "hold", "--marker", "configs/marker_coded.yaml", "--image-scale", "0.35",
                  "--duration", "3", "--no-progress", "--out", str(tmp_path / "run"), "--json", str(res_file))
    assert r.returncode == 0, r.stderr
    res = json.loads(res_file.read_text())
    c = res["closed_loop"]
    assert res["trajectory"]["orientation"] == "hold" and res["link"]["kind"] == "emulator"
    assert c["orientation_from"] == "optical tracker"
    assert c["orientation_mean_deg"] < 0.5 and c["orientation_max_deg"] < 2.0
    assert c["mean_mm"] < 0.5
    assert "orientation mean" in r.stdout
    probe = c["play_probe"]  # the default controller probes the plays first (a 6-DoF pose: the coded marker)
    assert isinstance(probe, list) and len(probe) == 6
    true_play = PlantParams.load(CONFIG_DIR / "plant.yaml").backlash
    backbones = [(f["play"], b) for f, b in zip(probe[2:], true_play[2:], strict=True) if f["ok"]]
    assert len(backbones) >= 2  # small images: the base's and the insertion's fits may be refused
    assert all(abs(p - b) < 12e-6 for p, b in backbones), backbones  # [m] of a 30 um play
    rows = (tmp_path / "run" / "log.csv").read_text().splitlines()
    header = rows[0].split(",")
    cols = [header.index(f"rot_des_{a}") for a in ("x", "y", "z")]
    held = {tuple(round(float(row.split(",")[i]), 9) for i in cols) for row in rows[1:] if ",servo," in row}
    assert len(held) == 1  # hold: one desired orientation for the whole walk


def test_paper_controller_refuses_an_orientation_before_any_motion() -> None:
    r = wristmark("servo", "--orientation", "follow", "--controller", "paper", "--duration", "1")
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "position-only" in lines[0], r.stderr


def test_without_ground_truth_the_vision_estimate_gives_the_orientation_errors() -> None:
    traj = Trajectory(np.array([[0.0, 0.0, 0.1], [0.01, 0.0, 0.1]]), 0.01)
    R_des = np.eye(3)
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.01), -np.sin(0.01)], [0.0, np.sin(0.01), np.cos(0.01)]])
    nan3 = np.full(3, np.nan)
    recs = [CycleRecord(t=0.06 * k, phase="servo", p_des=np.zeros(3), p_cmd=np.zeros(3), p_est=np.zeros(3),
                        p_true=nan3, p_trk=nan3, psi_cmd=np.zeros(6), psi_true=np.full(6, np.nan), meas_ok=True,
                        rejected=False, vision_ms=1.0, ctrl_us=1.0, R_des=R_des, R_est=tilt,
                        R_true=np.full((3, 3), np.nan), R_trk=np.full((3, 3), np.nan))  # as the loop records them
            for k in range(3)]
    assert orientation_errors_of(traj, recs) == {}  # the path asks for no orientation
    traj = traj.with_orientation("hold", RobotParams())
    out = orientation_errors_of(traj, recs)
    assert out["orientation_from"] == "vision estimate"
    assert abs(out["orientation_mean_deg"] - np.rad2deg(0.01)) < 1e-9
