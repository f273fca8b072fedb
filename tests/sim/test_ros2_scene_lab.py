"""The virtual lab of a scene over ROS 2 (`wristmark emulator --scene SCENE --ros2 NS`,
sim/ros2_scene_lab.py) as its own process: stdout names each arm's `--actuator` SPEC and the
`--camera` SPEC; this test, a DDS node on loopback (the loopback configuration set explicitly),
sees every sleeve in the endoscope's frames where the lab's truth has each arm, and moves arm a
alone through NS/a/crtk_command and NS/a/servo_jp while b stays disabled and still."""

from __future__ import annotations

import os
import random
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.rig.ros2.test_ros2_servo import env
from tests.sim.test_scene_lab import check_sleeves_at_truth
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG
from wristmark_testing.lab_process import read_lines, stop

pytestmark = [pytest.mark.network, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
SCENE = "configs/scenes/two_arms.yaml"
SCALE = 0.75  # as tests/sim/test_scene_lab.py (arm a's sleeve too small to track at 0.5 near the image edge)
NAMES = ["phi", "d", "s1a", "s1b", "s2a", "s2b"]


def test_each_arm_on_its_own_topics_and_one_endoscope_over_ros2(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.camera import scaled_stereo_camera
    from wristmark.cvs.sources.open_source import SourceOptions
    from wristmark.cvs.tracking.arm_set import ArmSetTracker
    from wristmark.models.marker import MarkerModel
    from wristmark.rig.loop.scene_file import Scene
    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.ros2.image_source import open_frame_source

    domain = random.randint(100, 199)
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_CONFIG)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    ns = f"wm_scene_lab_{os.getpid()}"
    truth, calib = tmp_path / "truth.csv", tmp_path / "calib.yaml"
    lab = subprocess.Popen(
        [sys.executable, "-m", "wristmark", "emulator", "--scene", SCENE, "--ros2", ns, "--fps", "10",
         "--watchdog", "2", "--image-scale", str(SCALE), "--truth-out", str(truth), "--calib-out", str(calib)],
        cwd=ROOT, env=env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        lines = read_lines(lab, 3, timeout=90)
        assert lines == [f"a ros2:/{ns}/a", f"b ros2:/{ns}/b",
                         f"ros2:/{ns}/left/image_raw/compressed,/{ns}/right/image_raw/compressed"]
        scene = Scene.load(SCENE)
        cam = scaled_stereo_camera(load_calibration(calib), SCALE)
        source = open_frame_source(lines[2], SourceOptions(timeout=20))
        try:
            frame = source.read()
        finally:
            source.close()
        check_sleeves_at_truth(ArmSetTracker(cam, [MarkerModel.load(a.marker) for a in scene.arms]), cam, frame, truth)
        # arm a alone enabled and moved 2 mm along d; b stays disabled where it was
        dp = DomainParticipant(domain)
        reliable = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(8))
        best = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(8))
        js = {n: DataReader(dp, Topic(dp, M.topic_name(f"/{ns}/{n}/measured_js"), M.JointState), best)
              for n in scene.names}
        state = {n: DataReader(dp, Topic(dp, M.topic_name(f"/{ns}/{n}/operating_state"), M.OperatingState),
                               Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(8),
                                   Policy.Durability.TransientLocal)) for n in scene.names}
        command = DataWriter(dp, Topic(dp, M.topic_name(f"/{ns}/a/crtk_command"), M.String), reliable)
        servo_jp = DataWriter(dp, Topic(dp, M.topic_name(f"/{ns}/a/servo_jp"), M.JointState), reliable)

        def latest(reader: Any, timeout: float = 5.0) -> Any:
            t_end, last = time.monotonic() + timeout, None
            while last is None and time.monotonic() < t_end:
                got = [m for m in reader.take(N=64) if hasattr(m, "header")]
                last = got[-1] if got else None
                time.sleep(0.02)
            assert last is not None
            return last

        start = {n: np.array(latest(js[n]).position) for n in scene.names}
        assert list(latest(js["a"]).name) == NAMES
        t_end = time.monotonic() + 5.0
        while min(w.get_publication_matched_status().current_count for w in (command, servo_jp)) < 1 \
                and time.monotonic() < t_end:
            time.sleep(0.05)
        command.write(M.String("enable"))
        goal = start["a"] + np.array([0.0, 0.002, 0.0, 0.0, 0.0, 0.0])
        for _ in range(30):  # 1.5 s of targets at 20 Hz (its watchdog 2 s: a loaded host's stall trips none)
            servo_jp.write(M.JointState(M.Header(M.Time(0, 0), ""), NAMES, [float(x) for x in goal], [], []))
            time.sleep(0.05)
        now = {n: np.array(latest(js[n]).position) for n in scene.names}
        states = {n: latest(state[n]).state for n in scene.names}
    finally:
        rc, err = stop(lab)
    assert rc == 0, err
    assert states == {"a": "ENABLED", "b": "DISABLED"}
    assert abs(now["a"][1] - goal[1]) < 0.2e-3, now["a"] - goal  # a reached its target insertion
    np.testing.assert_allclose(now["b"], start["b"], atol=1e-9)  # b never moved
    m = re.search(r"(\d+) frames, (\d+) targets", err)  # the lab's last line: what it obeyed (a's targets)
    assert m and int(m.group(1)) >= 1 and 25 <= int(m.group(2)) <= 30, err
