"""`wristmark servo --scene SCENE --actuator a=ros2:/NS/a --actuator b=ros2:/NS/b --camera ros2:...`
on the scene's virtual lab over ROS 2 (`wristmark emulator --scene SCENE --ros2 NS`, its own
process; the host in another, both on loopback in a random DDS domain): each arm's loop drives
its own arm's NS/NAME/servo_jp from the one endoscope's frames; both arms walk their cubes and
each true tip (the lab's truth) follows its desired tip. An arm disabled mid-run (this test, a
node on loopback, sends NS/b/crtk_command disable) is a safe stop of every arm: exit 3, one line."""

from __future__ import annotations

import json
import os
import random
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from tests.cli.test_cli_servo_live import no_probe_controller
from tests.rig.ros2.test_ros2_servo import env
from tests.sim.test_virtual_lab import NO_SIM, RT_HOST
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG
from wristmark_testing.lab_process import read_lines, stop

pytestmark = [pytest.mark.network, pytest.mark.slow, pytest.mark.wallclock]

ROOT = Path(__file__).resolve().parents[3]
SCENE = "configs/scenes/two_arms.yaml"
SCALE = 0.75  # as tests/rig/ros2/test_ros2_scene.py (at 0.5 arm a's sleeve is ~15 px across)
FPS = 16.67  # one frame per 60 ms cycle


@contextmanager
def ros2_scene_lab(tmp_path: Path, domain: int, ns: str) -> Iterator[tuple[dict[str, str], str, list[str]]]:
    """The scene's lab over ROS 2 in its own process: ({arm: its --actuator SPEC}, the --camera
    SPEC, [its exit status, its stderr] once stopped)."""
    truth, calib = tmp_path / "truth.csv", tmp_path / "calib.yaml"
    lab = subprocess.Popen(
        [sys.executable, "-m", "wristmark", "emulator", "--scene", SCENE, "--ros2", ns, "--fps", str(FPS),
         "--image-scale", str(SCALE), "--truth-out", str(truth), "--calib-out", str(calib)],
        cwd=ROOT, env=env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    ended: list[str] = []
    try:
        lines = read_lines(lab, 3, timeout=90)
        specs = dict(line.split(" ", 1) for line in lines[:2])
        assert specs == {"a": f"ros2:/{ns}/a", "b": f"ros2:/{ns}/b"}
        yield specs, lines[2], ended
    finally:
        rc, err = stop(lab)
        ended += [str(rc), err]


def host_command(tmp_path: Path, specs: dict[str, str], camera: str, duration: float) -> list[str]:
    """`wristmark servo --scene` on the lab's arms and camera (the simulated bench refused)."""
    return [sys.executable, "-c", NO_SIM, "servo", "--scene", SCENE,
            *[x for n, spec in specs.items() for x in ("--actuator", f"{n}={spec}")], "--camera", camera,
            "--calib", str(tmp_path / "calib.yaml"), "--image-scale", str(SCALE), "--duration", str(duration),
            "--settle", "0.3", "--controller-config", str(no_probe_controller(tmp_path)),
            "--out", str(tmp_path / "run"), "--no-progress", *RT_HOST]


def test_servo_scene_drives_each_arm_over_its_own_ros2_actuator(tmp_path: Path) -> None:
    from wristmark.rig.loop.scene_file import Scene
    from wristmark.sim.scene_lab import scene_true_tip_errors

    domain = random.randint(100, 199)
    with ros2_scene_lab(tmp_path, domain, f"wm_scene_host_{os.getpid()}") as (specs, camera, ended):
        host = subprocess.run(host_command(tmp_path, specs, camera, 3), cwd=ROOT, env=env(domain),
                              capture_output=True, text=True, timeout=180)
    assert host.returncode == 0, host.stdout + host.stderr
    assert ended[0] == "0", ended[1]
    out, truth = tmp_path / "run", tmp_path / "truth.csv"
    res = json.loads((out / "result.json").read_text())
    config = json.loads((out / "config.json").read_text())
    scene = Scene.load(SCENE)
    for a in scene.arms:
        arm = res["arms"][a.name]
        assert not arm["stopped"] and arm["safe_stop"]["held_and_disabled"], arm["safe_stop"]
        assert arm["link"]["port"] == specs[a.name] and config["arms"][a.name]["actuator"] == specs[a.name]
        # it reported DISABLED, then ENABLED after the host's enable (and DISABLED once more at the end, if heard)
        assert arm["link"]["operating_state_changes"] >= 2 and arm["link"]["malformed_measured_js"] == 0
        assert arm["closed_loop"]["cycles"] >= 30, arm["closed_loop"]
        assert f"servo --scene arm {a.name} (cube, " in host.stdout and f"link ros2 {specs[a.name]})" in host.stdout
        err = scene_true_tip_errors(out / f"log_{a.name}.csv", truth, a.name, a.base)  # vs its desired tip
        err = err[np.isfinite(err)]
        assert err.size >= 30, a.name
        print(f"arm {a.name}: true tip error median {1000 * np.median(err):.3f} mm, max {1000 * err.max():.3f} mm "
              f"over {err.size} cycles; {arm['link']['sent']} servo_jp sent, longest gap "
              f"{arm['link']['longest_servo_jp_gap_ms']} ms")
        assert arm["link"]["sent"] >= arm["closed_loop"]["cycles"]
        assert 1000 * np.median(err) < 1.0, a.name
    m = re.search(r"(\d+) frames, (\d+) targets, (\d+) watchdog trips", ended[1])  # the lab's last line
    sent = sum(res["arms"][n]["link"]["sent"] for n in scene.names)
    assert m and int(m.group(3)) == 0 and 0.9 * sent <= int(m.group(2)) <= sent, (sent, ended[1])


def disable_after_enabled(host: subprocess.Popen[str], ns: str, arm: str, after: float) -> float | None:
    """This test as a node on loopback (open_participant): ``after`` s after arm ``arm`` reports
    ENABLED, send it ``disable`` on its crtk_command; when it was ENABLED (None: never, or the host
    ended first)."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.ros2.dds_config import open_participant

    dp = open_participant()
    reliable = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(8))
    state = DataReader(dp, Topic(dp, M.topic_name(f"/{ns}/{arm}/operating_state"), M.OperatingState),
                       Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(8),
                           Policy.Durability.TransientLocal))
    command = DataWriter(dp, Topic(dp, M.topic_name(f"/{ns}/{arm}/crtk_command"), M.String), reliable)
    enabled_at = None
    deadline = time.monotonic() + 90
    while host.poll() is None and time.monotonic() < deadline:
        if enabled_at is None and any(getattr(s, "state", "") == "ENABLED" for s in state.take(N=16)):
            enabled_at = time.monotonic()
        if enabled_at is not None and time.monotonic() > enabled_at + after:  # the loops run: disabled
            command.write(M.String("disable"))
            return enabled_at
        time.sleep(0.05)
    return None


def test_an_arm_disabled_mid_run_is_a_safe_stop_of_every_arm_in_one_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    domain = random.randint(100, 199)
    for key, value in (("CYCLONEDDS_URI", LOOPBACK_CONFIG), ("ROS_DOMAIN_ID", str(domain))):
        monkeypatch.setenv(key, value)  # this test's own node: loopback, the lab's domain
    ns = f"wm_scene_stop_{os.getpid()}"
    with ros2_scene_lab(tmp_path, domain, ns) as (specs, camera, ended):
        host = subprocess.Popen(host_command(tmp_path, specs, camera, 20), cwd=ROOT, env=env(domain),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        enabled_at = disable_after_enabled(host, ns, "b", 2.0)
        stdout, err = host.communicate(timeout=60)
    assert enabled_at is not None, err
    assert host.returncode == 3, stdout + err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("wristmark servo: error: stopped safely: arm a at t = "), err
    assert "arm 'b'" in lines[0] and "reports DISABLED" in lines[0], lines[0]
    res = json.loads((tmp_path / "run" / "result.json").read_text())
    for n in ("a", "b"):  # every arm stopped (held and disabled) well before its 20 s walk ended
        arm = res["arms"][n]
        assert arm["stopped"] and arm["safe_stop"]["held_and_disabled"], arm
        assert arm["t_stop_s"] < 15, arm["t_stop_s"]
    assert ended[0] == "0", ended[1]
