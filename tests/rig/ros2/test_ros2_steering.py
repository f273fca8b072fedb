"""The done-when test of ROS 2 without ROS (#30): `wristmark servo --ros2 NS --target ros2` on the
simulated bench, and a second process that knows only the message definitions
(tests/rig/ros2/steer_client.py: Cyclone DDS and wristmark.rig.ros2.messages, nothing of the
loop) receives measured_cp / measured_js / setpoint_js, steers the tip through servo_cp and sees
the true tip follow; all on loopback (the loopback configuration set explicitly), in CI time
(about 20 s here)."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.rig.ros2.test_ros2_servo import ROOT, env, no_probe_controller
from wristmark.rig.recording.run_log import read_log_csv
from wristmark.sim.setup import load_setup

pytestmark = [pytest.mark.network, pytest.mark.slow, pytest.mark.wallclock]

DX_MM, DZ_MM, HOLD_S = 6.0, 4.0, 4.5


def test_a_ros2_node_steers_the_simulated_arm_through_servo_cp(tmp_path: Path) -> None:
    domain = random.randint(100, 199)  # away from other runs' participants on this host
    ns = f"wm_test_{os.getpid()}"
    servo = subprocess.Popen(
        [sys.executable, "-m", "wristmark", "servo", "--ros2", ns, "--target", "ros2", "--sensor", "truth-noise",
         "--duration", "8", "--settle", "0.3", "--controller-config", str(no_probe_controller(tmp_path)),
         "--no-progress", "--out", str(tmp_path / "run"), "--json", str(tmp_path / "res.json")],
        cwd=ROOT, env=env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = subprocess.Popen(
        [sys.executable, str(ROOT / "tests" / "rig" / "ros2" / "steer_client.py"), ns, str(DX_MM), str(DZ_MM),
         str(HOLD_S)], cwd=tmp_path, env=env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _, servo_err = servo.communicate(timeout=120)
        client_out, client_err = client.communicate(timeout=30)
    finally:
        servo.kill()
        client.kill()
    assert servo.returncode == 0, servo_err
    assert client.returncode == 0, client_err
    seen = json.loads(client_out)
    assert seen["loop_modules"] == []  # the node knew only the messages
    res = json.loads((tmp_path / "res.json").read_text())
    assert res["stopped"] == "" and res["safe_stop"]["held_and_disabled"]
    r2 = res["ros2"]
    assert r2["namespace"] == f"/{ns}" and r2["subscribed"] == [f"/{ns}/servo_cp"] and r2["publish_errors"] == 0
    tg = res["targets"]
    assert tg["received"] > 50 and tg["dropped"] == 2, tg  # the wrong frame_id and the NaN
    assert any("frame_id 'camera'" in k for k in tg["reasons"]) and sum("dropped" in ln for ln in
                                                                        servo_err.splitlines()) == 2
    # the node heard the loop: the tip, the measured and commanded actuators by name
    assert len(seen["measured"]) > 50 and min(seen["joints"].values()) > 50
    assert seen["names"]["measured_js"] == ["phi", "d", "s1a", "s1b", "s2a", "s2b"] == seen["names"]["setpoint_js"]
    # ... and the marker's pose beside the tip (frame world, checked by the node): the tip sits on
    # the marker's z axis at the marker's tip offset, within 1e-9 m
    tim = np.array(seen["tip_in_marker"]) - [0.0, 0.0, load_setup().params.tip_offset]
    assert seen["markers"] > 50 and len(tim) > 50, seen["markers"]
    assert np.abs(tim).max() < 1e-9, np.abs(tim).max()
    # ... and saw the tip follow its targets: near A at the end of A's hold, near B at the end
    t = np.array([m[0] for m in seen["measured"]])
    p = np.array([m[1] for m in seen["measured"]])
    sent_t = np.array([s[0] for s in seen["sent"]])
    sent_p = np.array([s[1] for s in seen["sent"]])
    start = sent_p[0] - [DX_MM / 1000, 0, 0]
    a, b = start + [DX_MM / 1000, 0, 0], start + [DX_MM / 1000, 0, DZ_MM / 1000]
    t_b = sent_t[np.argmax(np.linalg.norm(sent_p - b, axis=1) < 1e-9)]
    near_a = p[(t > t_b - 1.0) & (t < t_b)]
    near_b = p[(t > t[-1] - 1.0)]
    assert near_a.size and np.median(np.linalg.norm(near_a - a, axis=1)) < 0.5e-3
    assert near_b.size and np.median(np.linalg.norm(near_b - b, axis=1)) < 0.5e-3
    # the true arm (the simulated bench's truth, in the log) ended at B
    log = read_log_csv(tmp_path / "run" / "log.csv")
    p_true = np.stack([log[f"p_true_{c}"] for c in "xyz"], axis=1)
    assert np.linalg.norm(p_true[-5:] - b, axis=1).max() < 0.6e-3
