"""The whole loop over ROS 2: `wristmark servo --actuator ros2:NS --camera ros2:LEFT,RIGHT` (the
hardware path, real time, the tip only from tracking the frames) against the virtual lab over ROS 2
(``wristmark emulator --ros2 NS``, wristmark/sim/ros2_lab.py, in a process of its own: the
simulated arm behind NS/servo_jp, NS/crtk_command, NS/measured_js and its endoscope on two
CompressedImage topics), on loopback. The true arm reaches the point; the lab vanishing mid-run
is a safe stop in one line."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.rig.ros2.test_ros2_servo import ROOT, env, no_probe_controller

pytestmark = [pytest.mark.network, pytest.mark.slow, pytest.mark.wallclock]

SCALE = "0.25"


@pytest.fixture
def cli_lab(tmp_path: Path) -> Iterator[dict[str, Any]]:
    """``wristmark emulator --ros2 NS``: its first stdout lines are the --actuator and --camera SPECs."""
    ns = f"lab_{os.getpid()}_{random.randint(0, 9999)}"
    e = env(random.randint(100, 199))
    truth = tmp_path / "truth.csv"
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "emulator", "--ros2", ns, "--image-scale", SCALE,
                             "--fps", "15", "--truth-out", str(truth)], cwd=ROOT, env=e, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        actuator, camera = proc.stdout.readline().strip(), proc.stdout.readline().strip()
        assert actuator == f"ros2:/{ns}", proc.stderr.read() if proc.stderr and not actuator else actuator
        assert camera == f"ros2:/{ns}/left/image_raw/compressed,/{ns}/right/image_raw/compressed"
        yield {"ns": ns, "env": e, "truth": truth, "proc": proc}
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
        assert "frames" in err and "watchdog trips" in err, err  # its summary line on SIGTERM


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[dict[str, Any]]:
    ns = f"lab_{os.getpid()}_{random.randint(0, 9999)}"
    e = env(random.randint(100, 199))
    truth = tmp_path / "truth.csv"
    proc = subprocess.Popen([sys.executable, str(ROOT / "tests" / "rig" / "ros2" / "ros2_lab_main.py"), ns, SCALE,
                             "15", str(truth)], env=e, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        yield {"ns": ns, "env": e, "truth": truth, "proc": proc}
    finally:
        proc.kill()
        proc.communicate()


def servo(lab: dict[str, Any], tmp: Path, *extra: str) -> subprocess.Popen[str]:
    ns = lab["ns"]
    return subprocess.Popen(
        [sys.executable, "-m", "wristmark", "servo", "--actuator", f"ros2:{ns}",
         "--camera", f"ros2:/{ns}/left/image_raw/compressed,/{ns}/right/image_raw/compressed",
         "--image-scale", SCALE, "--controller-config", str(no_probe_controller(tmp)), "--settle", "0.5",
         "--no-progress", "--out", str(tmp / "run"), *extra],
        cwd=ROOT, env=lab["env"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def c_cycles(res: dict[str, Any]) -> int:
    return int(res["closed_loop"]["cycles"])


def test_the_loop_drives_the_virtual_lab_over_ros2(cli_lab: dict[str, Any], tmp_path: Path) -> None:
    lab = cli_lab
    p = servo(lab, tmp_path, "--trajectory", "point", "--point", "0.0797", "0.0", "0.1449", "--duration", "3",
              "--ros2", lab["ns"] + "_host")
    out, err = p.communicate(timeout=180)
    assert p.returncode == 0, err
    res = json.loads((tmp_path / "run" / "result.json").read_text())
    c = res["closed_loop"]
    assert res["link"]["kind"] == "ros2" and res["link"]["port"] == f"ros2:/{lab['ns']}" and res["link"]["realtime"]
    assert res["link"]["sent"] > c_cycles(res) and res["link"]["malformed_measured_js"] == 0
    assert res["sensor"] == "vision (camera)" and res["frames"]["wall_clock"]
    assert c["cycles"] >= 40 and c["lost"] <= 10 and c["rejected"] <= 2, c
    assert c["mean_mm"] < 0.6, c
    assert res["safe_stop"]["held_and_disabled"] and res["ros2"]["publish_errors"] == 0
    truth = np.loadtxt(lab["truth"], delimiter=",", skiprows=1)
    assert np.linalg.norm(truth[-5:, 1:] - [0.0797, 0.0, 0.1449], axis=1).max() < 0.6e-3  # the true arm is there
    assert "capture -> command median" in out


def test_the_lab_vanishing_mid_run_is_a_safe_stop_in_one_line(lab: dict[str, Any], tmp_path: Path) -> None:
    p = servo(lab, tmp_path, "--trajectory", "cube", "--duration", "20")
    assert lab["proc"].stdout.readline().strip() == "enabled"  # the host enabled the arm
    time.sleep(4.0)  # the start move and settle, the walk under way
    assert p.poll() is None
    lab["proc"].kill()
    _, err = p.communicate(timeout=60)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert p.returncode == 3 and len(lines) == 1, err
    assert "stopped safely" in lines[0] and ("silent" in lines[0] or "no stereo pair" in lines[0]), lines[0]
