"""`wristmark servo --scene SCENE --ros2 NS --target a=ros2 --hold b` on the scene's virtual lab
(`wristmark emulator --scene SCENE --pty --camera-port 0`, its own process; the host in another):
this test, a ROS 2 node on loopback (the loopback configuration set explicitly), hears each arm on
NS/NAME/measured_cp, in the scene's {w}, exactly the tips of that arm's log stamped with their
frames' capture, and steers arm a through NS/a/servo_cp while b holds its centre; a's true tip
(the lab's truth) ends at the sent target."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.cli.test_cli_servo_live import no_probe_controller
from tests.rig.ros2.test_ros2_servo import env
from tests.sim.test_virtual_lab import NO_SIM, RT_HOST, RT_LAB
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG
from wristmark_testing.lab_process import read_lines, scene_lab_command, stop

pytestmark = [pytest.mark.network, pytest.mark.slow, pytest.mark.wallclock]

ROOT = Path(__file__).resolve().parents[3]
SCENE = "configs/scenes/two_arms.yaml"
SCALE = 0.75  # as tests/sim/test_scene_lab.py and docs/notes/several-arms.md: at 0.5 arm a's sleeve is ~15 px across
FPS = 16.67  # one frame per 60 ms cycle
UP = np.array([0.003, 0.0, 0.003])  # a's target: 3 mm off its centre in x and z of its own {w}


def log_tips(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(p_est (N, 3) [m], t_capture (N,) [s]) of the cycles of a log with a measured tip."""
    from wristmark.rig.recording.run_log import read_log_csv

    log = read_log_csv(path)
    p = np.stack([np.asarray(log[f"p_est_{x}"], float) for x in "xyz"], axis=1)
    t = np.asarray(log["t_capture"], float)
    ok = np.all(np.isfinite(p), axis=1)
    return p[ok], t[ok]


def test_servo_scene_on_ros2_publishes_every_arm_and_a_follows_its_servo_cp(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wristmark.rig.loop.arm_set_session import load_scene_setups
    from wristmark.rig.loop.scene_file import Scene
    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.targets.trajectories import workspace_centre
    from wristmark.sim.scene_lab import read_scene_truth_csv, scene_true_tip_errors

    domain = random.randint(100, 199)
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_CONFIG)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    ns = f"wm_scene_{os.getpid()}"
    truth, calib, out = tmp_path / "truth.csv", tmp_path / "calib.yaml", tmp_path / "run"
    lab = subprocess.Popen(scene_lab_command(SCENE, SCALE, FPS, str(truth), str(calib), *RT_LAB), cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        lines = read_lines(lab, 3, timeout=90)
        ptys = dict(line.split(" ", 1) for line in lines[:2])
        scene = Scene.load(SCENE)
        setups, _ = load_scene_setups(scene, calib)
        bases = {a.name: a.base for a in scene.arms}
        centre = {n: workspace_centre(s.params, scene.cube_size) for n, s in setups.items()}  # each arm's {w}
        goal = bases["a"][:3, :3] @ (centre["a"] + UP) + bases["a"][:3, 3]  # in the scene's {w}
        dp = DomainParticipant(domain)
        qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(1000))
        readers = {n: DataReader(dp, Topic(dp, M.topic_name(f"/{ns}/{n}/measured_cp"), M.PoseStamped), qos)
                   for n in scene.names}
        writer = DataWriter(dp, Topic(dp, M.topic_name(f"/{ns}/a/servo_cp"), M.PoseStamped), qos)
        host = subprocess.Popen(
            [sys.executable, "-c", NO_SIM, "servo", "--scene", SCENE, "--serial", f"a={ptys['a']}", "--serial",
             f"b={ptys['b']}", "--camera", lines[2], "--calib", str(calib), "--image-scale", str(SCALE),
             "--ros2", ns, "--target", "a=ros2", "--hold", "b", "--duration", "3", "--settle", "0.3",
             "--target-timeout", "1", "--controller-config", str(no_probe_controller(tmp_path)), "--out", str(out),
             "--no-progress", *RT_HOST], cwd=ROOT, env=env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True)
        got: dict[str, list[Any]] = {n: [] for n in scene.names}
        sent = 0
        deadline = time.monotonic() + 120
        while host.poll() is None and time.monotonic() < deadline:
            for n, r in readers.items():
                got[n] += [m for m in r.take(N=256) if hasattr(m, "pose")]
            if got["a"]:  # the loop runs: a's target at 10 Hz
                writer.write(M.pose_stamped(time.time(), "world", goal.tolist()))
                sent += 1
            time.sleep(0.1)
        stdout, err = host.communicate(timeout=30)
        time.sleep(0.3)
        for n, r in readers.items():
            got[n] += [m for m in r.take(N=256) if hasattr(m, "pose")]
    finally:
        rc, lab_err = stop(lab)
        assert rc == 0, lab_err
    assert host.returncode == 0, stdout + err
    res = json.loads((out / "result.json").read_text())
    arm_a, arm_b = res["arms"]["a"], res["arms"]["b"]
    assert (arm_a["walk"], arm_b["walk"]) == ("ros2", "hold") and "targets" not in arm_b
    for n in scene.names:  # one namespace per arm, a subscribed to its own servo_cp only
        r2 = res["arms"][n]["ros2"]
        assert r2["namespace"] == f"/{ns}/{n}" and r2["publish_errors"] == 0
        assert r2["subscribed"] == ([f"/{ns}/a/servo_cp"] if n == "a" else [])
    assert 10 <= arm_a["targets"]["received"] <= sent and arm_a["targets"]["dropped"] == 0
    for n in scene.names:  # each arm's measured_cp: its log's tips in the scene's {w}, stamped at their capture
        p_log, t_log = log_tips(out / f"log_{n}.csv")
        B = bases[n]
        assert len(got[n]) >= 0.9 * len(p_log) > 20, (n, len(got[n]), len(p_log))
        rows, offsets = [], []
        for m in got[n]:
            assert m.header.frame_id == "world"
            pos = np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z])
            d = np.linalg.norm(p_log - (B[:3, :3].T @ (pos - B[:3, 3])), axis=1)
            assert d.min() < 1e-8, (n, d.min())
            rows.append(int(d.argmin()))
            offsets.append(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec - t_log[rows[-1]])
        assert np.all(np.diff(rows) > 0)  # in the log's order, none twice
        assert np.ptp(offsets) < 1e-4  # one clock offset: every stamp its frame's capture
    t, tips = read_scene_truth_csv(truth)
    t_a = log_tips(out / "log_a.csv")[1]
    late = t_a[t_a > t_a[-1] - 1.0]  # a's last second of cycles: at its target
    true_a = np.stack([np.interp(late, t, tips["a"][:, i]) for i in range(3)], axis=1)  # scene {w}
    seen_a = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in got["a"][-len(late):]])
    true_err, seen_err = np.linalg.norm(true_a - goal, axis=1), np.linalg.norm(seen_a - goal, axis=1)
    print(f"a, last second: true tip median {1000 * np.median(true_err):.3f} mm from the sent target, measured_cp "
          f"{1000 * np.median(seen_err):.3f} mm; {len(got['a'])} + {len(got['b'])} measured_cp, "
          f"{arm_a['targets']['received']} of {sent} targets used")
    assert np.median(true_err) < 0.5e-3 and np.median(seen_err) < 0.5e-3
    assert np.linalg.norm(true_a[-1] - goal) < np.linalg.norm(UP) / 2  # there, not at its centre
    err_b = scene_true_tip_errors(out / "log_b.csv", truth, "b", bases["b"])  # vs b's centre (its desired tip)
    err_b = err_b[np.isfinite(err_b)]
    assert err_b.size >= 30 and 1000 * np.median(err_b) < 1.0
