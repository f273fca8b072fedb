"""`wristmark track --ros2 NS`: a reader in this process (the loopback configuration, a random
domain) receives NS/measured_cp and NS/marker/measured_cp from the command in its own process and
finds the tip and the marker's origin of its --json lines (in {w} with the calibration's
world_T_left, frame_id world; else in {ll}, frame_id left_camera), a pair without a pose
publishing nothing; without cyclonedds --ros2 is one line."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from tests.rig.ros2.test_ros2_servo import ROOT, env
from wristmark.cvs.calibration.load import load_calibration
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG

pytestmark = [pytest.mark.network]

EXAMPLE = ROOT / "docs" / "example"
ARGS = ["--marker", str(EXAMPLE / "marker.yaml"), "--axis-hint", "1", "0", "0", "--json"]


class Readers:
    """The two topics' readers on a fresh participant in ``domain`` (the fixture set the loopback configuration)."""

    def __init__(self, ns: str, domain: int) -> None:
        from cyclonedds.core import Policy, Qos
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2.messages import PoseStamped, topic_name

        self.dp = DomainParticipant(domain)
        qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(64))
        self.readers = {n: DataReader(self.dp, Topic(self.dp, topic_name(f"/{ns}/{n}"), PoseStamped), qos)
                        for n in ("measured_cp", "marker/measured_cp")}
        self.got: dict[str, list[Any]] = {n: [] for n in self.readers}

    def take(self, want: int, timeout: float = 5.0) -> dict[str, list[Any]]:
        """Everything received, waiting up to ``timeout`` [s] for ``want`` samples on each topic."""
        t_end = time.monotonic() + timeout
        while True:
            for n, r in self.readers.items():
                self.got[n] += [m for m in r.take(N=64) if hasattr(m, "pose")]
            if all(len(v) >= want for v in self.got.values()) or time.monotonic() > t_end:
                return self.got
            time.sleep(0.02)


@pytest.fixture
def loopback(monkeypatch: pytest.MonkeyPatch) -> int:
    """A random domain in 100-199 and the loopback configuration in this process."""
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_CONFIG)
    domain = random.randint(100, 199)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    return domain


def run_track(argv: list[str], domain: int) -> tuple[list[dict[str, Any]], str, float, float]:
    """``wristmark track ARGV`` in its own process: its JSON lines, stderr, and the system clock before and after."""
    t0 = time.time()
    r = subprocess.run([sys.executable, "-m", "wristmark", "track", *argv], cwd=ROOT, env=env(domain),
                       capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stderr
    return [json.loads(x) for x in r.stdout.splitlines() if x.strip()], r.stderr, t0, time.time()


def stamp_of(msg: Any) -> float:
    """A header's stamp [s]."""
    return float(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)


def check_pose(msg: Any, frame_id: str, p: np.ndarray, R: np.ndarray) -> None:
    """``msg`` is at ``p`` [m] (within 1e-9) with the orientation ``R`` in ``frame_id``."""
    assert msg.header.frame_id == frame_id
    pos, q = msg.pose.position, msg.pose.orientation
    assert np.abs(np.array([pos.x, pos.y, pos.z]) - p).max() < 1e-9
    got = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    assert np.abs(got - R).max() < 1e-6


@pytest.mark.slow
def test_track_source_publishes_the_json_tip_and_marker_in_world(loopback: int) -> None:
    ns = f"wm_track_{os.getpid()}"
    readers = Readers(ns, loopback)
    lines, err, t0, t1 = run_track(["--ros2", ns, "--source", str(EXAMPLE), "--calib", str(EXAMPLE / "calib.yaml"),
                                    *ARGS], loopback)
    got = readers.take(len(lines))
    W = np.asarray(load_calibration(EXAMPLE / "calib.yaml").T_world_left, float)
    assert len(lines) == 1 and lines[0]["ok"], lines
    assert len(got["measured_cp"]) == len(got["marker/measured_cp"]) == 1, got
    o = lines[0]
    R_w = W[:3, :3] @ np.array(o["R"])
    check_pose(got["measured_cp"][0], "world", W[:3, :3] @ np.array(o["tip"]) + W[:3, 3], R_w)
    check_pose(got["marker/measured_cp"][0], "world", W[:3, :3] @ np.array(o["t"]) + W[:3, 3], R_w)
    stamp = stamp_of(got["measured_cp"][0])
    assert stamp == stamp_of(got["marker/measured_cp"][0]) and t0 < stamp < t1  # the capture, on the system clock
    assert f"1 pairs published on /{ns}/measured_cp and /{ns}/marker/measured_cp (frame_id world)" in err


@pytest.mark.slow
def test_track_pairs_without_world_publish_in_left_camera_and_nothing_without_a_pose(loopback: int,
                                                                                     tmp_path: Path) -> None:
    calib = yaml.safe_load((EXAMPLE / "calib.yaml").read_text())
    del calib["world_T_left"]
    (tmp_path / "calib.yaml").write_text(yaml.safe_dump(calib))
    w, h = calib["image_size"]
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((h, w, 3), 110, np.uint8))
    pair = [str(EXAMPLE / "pair_00_left.jpg"), str(EXAMPLE / "pair_00_right.jpg")]
    ns = f"wm_track_ll_{os.getpid()}"
    readers = Readers(ns, loopback)
    lines, err, _, _ = run_track(["--ros2", ns, "--calib", str(tmp_path / "calib.yaml"), *ARGS, str(blank),
                                  str(blank), *pair], loopback)
    got = readers.take(2, timeout=3.0)  # two would be one too many: the blank pair publishes nothing
    assert [o["ok"] for o in lines] == [False, True], lines
    assert len(got["measured_cp"]) == len(got["marker/measured_cp"]) == 1, got
    o = lines[1]
    check_pose(got["measured_cp"][0], "left_camera", np.array(o["tip"]), np.array(o["R"]))
    check_pose(got["marker/measured_cp"][0], "left_camera", np.array(o["t"]), np.array(o["R"]))
    assert "1 pairs published" in err and "(frame_id left_camera), 1 without a pose" in err


def test_track_ros2_without_cyclonedds_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "sitecustomize.py"  # cyclonedds made unimportable in the child
    blocker.write_text("import sys\nclass _Block:\n    def find_spec(self, name, path=None, target=None):\n"
                       "        if name.split('.')[0] == 'cyclonedds':\n"
                       "            raise ModuleNotFoundError(\"No module named 'cyclonedds'\")\n"
                       "sys.meta_path.insert(0, _Block())\n")
    e = {**env(0), "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}"}
    r = subprocess.run([sys.executable, "-m", "wristmark", "track", "--ros2", "--source", str(EXAMPLE), "--calib",
                        str(EXAMPLE / "calib.yaml")], cwd=ROOT, env=e, capture_output=True, text=True, timeout=60)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and r.stdout == "", r.stderr
    assert "--ros2" in lines[0] and "cyclonedds" in lines[0] and "wristmark[ros2]" in lines[0]


def test_track_ros2_bad_namespace_is_one_line() -> None:
    r = subprocess.run([sys.executable, "-m", "wristmark", "track", "--ros2", "1bad/ns", "--source", str(EXAMPLE),
                        "--calib", str(EXAMPLE / "calib.yaml")], cwd=ROOT, env=env(0), capture_output=True,
                       text=True, timeout=60)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "--ros2" in lines[0] and "namespace" in lines[0], r.stderr
