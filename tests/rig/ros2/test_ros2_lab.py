"""The whole loop over ROS 2: `wristmark servo --actuator ros2:NS --camera ros2:LEFT,RIGHT` (the
hardware path, real time, the tip only from tracking the frames) against the virtual lab over ROS 2
(``wristmark emulator --ros2 NS``, wristmark/sim/ros2_lab.py, in a process of its own: the
simulated arm behind NS/servo_jp, NS/crtk_command, NS/measured_js and its endoscope on two
CompressedImage topics), on loopback. The true arm reaches the point; the lab vanishing mid-run
is a safe stop in one line; so is the lab's watchdog disabling the arm (NS/operating_state), and an
arm that publishes no operating_state is not moved (unless --no-operating-state)."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.rig.ros2.test_ros2_servo import ROOT, env, no_probe_controller

pytestmark = [pytest.mark.network, pytest.mark.slow, pytest.mark.wallclock]

SCALE = "0.25"


@contextmanager
def emulator(tmp_path: Path, *extra: str) -> Iterator[dict[str, Any]]:
    """``wristmark emulator --ros2 NS``: its first stdout lines are the --actuator and --camera SPECs;
    ``summary``: its last stderr line (on SIGTERM), filled in on leaving."""
    ns = f"lab_{os.getpid()}_{random.randint(0, 9999)}"
    e = env(random.randint(100, 199))
    truth = tmp_path / "truth.csv"
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "emulator", "--ros2", ns, "--image-scale", SCALE,
                             "--fps", "15", "--truth-out", str(truth), *extra], cwd=ROOT, env=e,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lab = {"ns": ns, "env": e, "truth": truth, "proc": proc, "summary": ""}
    try:
        assert proc.stdout is not None
        actuator, camera = proc.stdout.readline().strip(), proc.stdout.readline().strip()
        assert actuator == f"ros2:/{ns}", proc.stderr.read() if proc.stderr and not actuator else actuator
        assert camera == f"ros2:/{ns}/left/image_raw/compressed,/{ns}/right/image_raw/compressed"
        yield lab
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
        assert "frames" in err and "watchdog trips" in err, err  # its summary line on SIGTERM
        lab["summary"] = err.strip().splitlines()[-1]


@pytest.fixture
def cli_lab(tmp_path: Path) -> Iterator[dict[str, Any]]:
    with emulator(tmp_path) as lab:
        yield lab


@contextmanager
def lab_main(tmp_path: Path, *extra: str) -> Iterator[dict[str, Any]]:
    """tests/rig/ros2/ros2_lab_main.py in a process of its own (prints ready, enabled)."""
    ns = f"lab_{os.getpid()}_{random.randint(0, 9999)}"
    e = env(random.randint(100, 199))
    truth = tmp_path / "truth.csv"
    proc = subprocess.Popen([sys.executable, str(ROOT / "tests" / "rig" / "ros2" / "ros2_lab_main.py"), ns, SCALE,
                             "15", str(truth), *extra], env=e, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        yield {"ns": ns, "env": e, "truth": truth, "proc": proc}
    finally:
        proc.kill()
        proc.communicate()


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[dict[str, Any]]:
    with lab_main(tmp_path) as lab:
        yield lab


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


def assert_the_marker_stayed_in_sight(c: dict[str, Any]) -> None:
    """A run's lost cycles (``closed_loop``), told apart. A cycle without a new frame steps on the
    last measurement: the lab's 15 fps camera under the 60 ms loop leaves one cycle in ten without
    one (measured 6 of 51 on the point, 7-8 of 67 on the tendon arm's cube), a loaded host's late
    frames more, so at most twice that. A frame that came and gave no measurement is the tracker's
    (0-2 of 67 measured on the tendon arm's cube, idle and beside a busy core): at most 3."""
    assert c["reused"] == c["no_frame"] <= 0.2 * c["cycles"], c
    assert c["lost"] - c["no_frame"] <= 3, c


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
    assert c["cycles"] >= 40 and c["rejected"] <= 2, c
    assert_the_marker_stayed_in_sight(c)
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


def one_line(p: subprocess.Popen[str], timeout: float = 120) -> str:
    """The servo's only stderr line (it failed: exit 3)."""
    _, err = p.communicate(timeout=timeout)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert p.returncode == 3 and len(lines) == 1, (p.returncode, err)
    return lines[0]


def test_the_labs_watchdog_disabling_the_arm_is_a_safe_stop_in_one_line(tmp_path: Path) -> None:
    """The bug: the host stalled past the lab's watchdog, the lab held and disabled the arm, measured_js
    kept coming, and the host servoed on and exited 0 (this run, before the fix: 45 cycles on the
    disabled arm until the vision gates gave up, "marker lost"). Here the lab's watchdog is 20 ms, shorter than
    the host's keep-alive (50 ms) and its cycle, so the host's ordinary cycle trips it every time:
    the lab reports DISABLED on operating_state and the host stops (exit 3, one line), no longer
    servoing an arm that does not obey."""
    with emulator(tmp_path, "--watchdog", "0.02") as lab:
        p = servo(lab, tmp_path, "--trajectory", "point", "--point", "0.0797", "0.0", "0.1449", "--duration", "3")
        line = one_line(p)
    assert "stopped safely" in line and "the arm reports DISABLED (its watchdog or an operator" in line, line
    trips = int(lab["summary"].split(" watchdog trips")[0].rsplit(" ", 1)[-1])
    assert trips >= 1, lab["summary"]  # the lab's watchdog did trip
    res = json.loads((tmp_path / "run" / "result.json").read_text())
    assert res["safe_stop"]["held_and_disabled"], res["safe_stop"]
    assert res["link"]["operating_state"] == "DISABLED" and res["link"]["operating_state_required"], res["link"]


def test_an_arm_without_operating_state_is_not_moved_unless_told_unsafe(tmp_path: Path) -> None:
    """An arm driver that publishes no operating_state: the host enables it, hears no state within
    the bounded wait and refuses in one line (exit 3) before any target; --no-operating-state
    drives it (the documented unsafe opt-out)."""
    with lab_main(tmp_path, "no-operating-state") as lab:
        p = servo(lab, tmp_path, "--trajectory", "point", "--point", "0.0797", "0.0", "0.1449", "--duration", "2")
        line = one_line(p)
        assert "before the first target" in line and "no operating_state from the arm" in line, line
        assert "--no-operating-state" in line, line
        res = json.loads((tmp_path / "run" / "result.json").read_text())
        assert res["link"]["sent"] <= 1 and res["link"]["operating_state"] is None, res["link"]  # a hold at most
        truth = np.loadtxt(lab["truth"], delimiter=",", skiprows=1)
        assert np.linalg.norm(truth[:, 1:] - truth[0, 1:], axis=1).max() < 1e-5  # nothing moved

        p = servo(lab, tmp_path, "--trajectory", "point", "--point", "0.0797", "0.0", "0.1449", "--duration", "2",
                  "--no-operating-state", "--force")
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0, err
        res = json.loads((tmp_path / "run" / "result.json").read_text())
        assert not res["link"]["operating_state_required"] and c_cycles(res) >= 20, res["link"]


def test_an_operator_disabling_the_arm_mid_walk_is_a_safe_stop_in_one_line(lab: dict[str, Any], tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Another node sends ``disable`` on crtk_command mid-walk: the lab holds and reports DISABLED,
    and the host stops there in one line (exit 3) instead of servoing on."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.pub import DataWriter
    from cyclonedds.topic import Topic

    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.ros2.dds_config import open_participant

    for k in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID"):
        monkeypatch.setenv(k, lab["env"][k])
    p = servo(lab, tmp_path, "--trajectory", "cube", "--duration", "20")
    assert lab["proc"].stdout.readline().strip() == "enabled"
    dp = open_participant()
    operator = DataWriter(dp, Topic(dp, M.topic_name(f"{lab['ns']}/crtk_command"), M.String),
                          Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(1)))
    time.sleep(4.0)  # the start move and settle, the walk under way
    assert p.poll() is None and operator.get_publication_matched_status().current_count >= 1
    operator.write(M.String("disable"))
    line = one_line(p, timeout=60)
    assert "the arm reports DISABLED (its watchdog or an operator" in line and "at t = " in line, line
    res = json.loads((tmp_path / "run" / "result.json").read_text())
    assert res["link"]["operating_state"] == "DISABLED" and res["safe_stop"]["held_and_disabled"], res


def test_the_loop_walks_a_format2_arm_on_the_ros2_lab(tmp_path: Path) -> None:
    """`wristmark emulator --ros2 NS --robot tendon3.yaml`: JointState names from the robot file
    (d, s1a, ..., s3c), the endoscope framed for the arm (--calib-out for the host); the host's
    `servo --actuator ros2:NS --robot tendon3.yaml --calib C` walks the cube and the true arm follows."""
    from wristmark.models.arm_spec import actuator_names, load_arm
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.rig.loop.metrics import error_stats
    from wristmark.sim.virtual_lab import true_tip_errors

    robot = CONFIG_DIR / "robots" / "tendon3.yaml"
    calib = tmp_path / "lab_calib.yaml"
    with emulator(tmp_path, "--robot", str(robot), "--calib-out", str(calib)) as lab:
        p = servo(lab, tmp_path, "--robot", str(robot), "--calib", str(calib), "--trajectory", "cube",
                  "--duration", "4", "--ros2", lab["ns"] + "_host")
        _, err = p.communicate(timeout=240)
    assert p.returncode == 0, err
    res = json.loads((tmp_path / "run" / "result.json").read_text())
    c = res["closed_loop"]
    # the host reads measured_js by the arm's ten names (d, s1a, ..., s3c): none malformed, none missing
    assert res["link"]["kind"] == "ros2" and res["link"]["malformed_measured_js"] == 0 and res["link"]["sent"] > 50
    assert len(actuator_names(load_arm(robot))) == 10
    assert "psi_cmd_theta3" in (tmp_path / "run" / "log.csv").read_text().splitlines()[0]
    assert c["cycles"] >= 50 and res["safe_stop"]["held_and_disabled"], c
    assert_the_marker_stayed_in_sight(c)  # as the point above
    assert res["ros2"]["publish_errors"] == 0
    true = error_stats(true_tip_errors(tmp_path / "run" / "log.csv", lab["truth"]))
    print(f"\ntendon3 over ROS 2: true tip {true.mean_mm:.3f} / {true.max_mm:.3f} mm over {true.n} cycles; "
          f"vision {c['mean_mm']:.3f} / {c['max_mm']:.3f} mm")
    # measured 2026-12-03 (4 s of the cube at 0.25 x, 15 fps, load 5): 0.278 / 0.467 mm; ~2 x margin for a
    # loaded host, below the open loop of this plant (1.34 / 2.57 mm over the full cube)
    assert true.n >= 50 and true.mean_mm < 0.6 and true.max_mm < 2.0
