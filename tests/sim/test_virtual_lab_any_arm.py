"""The virtual lab plays any arm: `wristmark emulator --pty --camera-port 0 --robot FILE` frames a
format-2 arm with its endoscope (the simulated bench's placement), writes the calibration the host
needs (--calib-out), and the hardware path `wristmark servo --serial PTY --camera URL --robot FILE
--calib C` (the simulated bench unimportable) walks the cube on it over the real pty (protocol v2)
and the real MJPEG stream; the true tip from --truth-dense-out."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.sim.test_virtual_lab import RT_HOST, RT_LAB, hardware_servo, read_lines
from wristmark.cvs.calibration.load import load_calibration
from wristmark.models.config_files import CONFIG_DIR, default_config
from wristmark.rig.loop.metrics import error_stats
from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED
from wristmark.sim.virtual_lab import true_tip_errors

ROOT = Path(__file__).resolve().parents[2]
ROBOTS = CONFIG_DIR / "robots"
SCALE, FPS = 0.35, 30.0
CUBE_S = 6.0  # [s] of the cube's walk, after the ramp from home and the settle
# (m actuators, bound on the walk's true-tip mean and max [mm]). Measured on the shared 2-core
# machine (load 5, 6 s of the cube at 0.35 x, 30 fps): tendon3 0.182 / 0.589, single_tendon
# 0.184 / 0.877, planar 0.162 / 0.534 mm; the bounds leave ~2 x margin on the mean and ~1.7 x on
# the max (a loaded host's timing moves single cycles), below what no loop gives (the full
# cube's open loop on these plants: 0.9-1.7 mm mean, 1.8-3.6 mm max).
ARMS = {"tendon3": (10, 0.4, 1.5), "single_tendon": (6, 0.4, 1.5), "planar": (5, 0.4, 1.5)}


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
@pytest.mark.parametrize("name", list(ARMS))
def test_servo_walks_the_cube_on_the_virtual_lab_of_a_format2_arm(tmp_path: Path, name: str) -> None:
    robot = ROBOTS / f"{name}.yaml"
    calib, dense = tmp_path / "lab_calib.yaml", tmp_path / "truth_dense.csv"
    lab = subprocess.Popen(
        [sys.executable, "-m", "wristmark", "emulator", "--pty", "--camera-port", "0", "--robot", str(robot),
         "--fps", str(FPS), "--image-scale", str(SCALE), "--jpeg-quality", "95", "--calib-out", str(calib),
         "--truth-dense-out", str(dense), *RT_LAB],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        pty, url = read_lines(lab, 2, timeout=90)
        r = hardware_servo("--serial", pty, "--camera", url, "--robot", str(robot), "--calib", str(calib),
                           "--image-scale", str(SCALE), *RT_HOST, "--trajectory", "cube", "--duration", str(CUBE_S),
                           "--no-progress", "--out", str(tmp_path / "run"), "--json", str(tmp_path / "res.json"),
                           timeout=240)
    finally:
        lab.send_signal(signal.SIGTERM)
        _, lab_err = lab.communicate(timeout=30)
    assert r.returncode == 0, r.stderr
    assert lab.returncode == 0, lab_err.decode(errors="replace")
    # the lab placed its endoscope for this arm, not where configs/camera.yaml says
    placed = load_calibration(calib).T_world_left
    shipped = load_calibration(default_config("camera.yaml")).T_world_left
    assert placed is not None and shipped is not None and np.abs(np.asarray(placed) - shipped).max() > 1e-3
    res = json.loads((tmp_path / "res.json").read_text())
    m, mean_bound, max_bound = ARMS[name]
    assert res["link"]["protocol"] == {"version": 2, "actuators": m}
    assert res["stopped"] == "" and res["safe_stop"]["held_and_disabled"]
    c = res["closed_loop"]
    # tracked in nearly every frame it used: planar lost 1 of ~100 in two runs of three (load 5-8); the loop
    # steps over up to max_lost_cycles (25) without a measurement, and the true tip below says what it cost
    assert c["errors_from"] == "vision estimate" and c["lost"] <= 5
    err = true_tip_errors(tmp_path / "run" / "log.csv", dense)
    stats = error_stats(err)
    print(f"\n{name} on the virtual lab: true tip {stats.mean_mm:.3f} / {stats.max_mm:.3f} mm mean / max over "
          f"{stats.n} cycles; vision {c['mean_mm']:.3f} / {c['max_mm']:.3f} mm")
    assert stats.n == c["cycles"] >= 0.8 * CUBE_S / 0.06
    assert stats.mean_mm < mean_bound and stats.max_mm < max_bound
    # converged: along the cube's first edge (straight, 4 s), its second half no worse than its first
    # (no drift, no growing oscillation). Not the window's halves: its second half holds the corner
    # onto the y edge and the first none: planar's second half came 0.04-0.07 mm above its first in
    # the 4 runs looked at, over 0.1 mm in 5 of 17 runs (2026-12-04); on the edge: -0.06 to +0.03 mm
    t = np.array([float(row["t"]) for row in csv.DictReader(open(tmp_path / "run" / "log.csv"))
                  if row["phase"] == "servo"])
    assert t.size == err.size
    t -= t[0]
    edge = CUBE_SIZE[0] / CUBE_SPEED
    assert CUBE_S > edge
    first, second = err[t < edge / 2], err[(t >= edge / 2) & (t < edge)]
    first, second = first[np.isfinite(first)], second[np.isfinite(second)]
    assert first.size > 20 and second.size > 20
    assert float(np.mean(second)) < float(np.mean(first)) + 0.1e-3
