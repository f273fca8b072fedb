"""A stereo camera on ROS 2 as a frame source (rig/ros2/image_source.py, ``ros2:LEFT,RIGHT``):
pairing by stamp, the spec's one-line errors, and ``wristmark track --source ros2:...`` on rendered
pairs published by another process that knows only the message types (raw Image and JPEG
CompressedImage), on loopback."""

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

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration, save_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.sources.frames import FrameSourceError
from wristmark.models.config_files import CONFIG_DIR
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG
from wristmark.rig.ros2.image_source import Received, StereoPairer, parse_ros2_spec
from wristmark.sim.render.motion_video import render_motion

pytestmark = [pytest.mark.network]

ROOT = Path(__file__).resolve().parents[3]
N = 4


def item(stamp_ms: float, arrival: float = 0.0, tag: str = "") -> Received:
    return Received(int(stamp_ms * 1_000_000), arrival, tag)


def test_left_and_right_pair_by_stamp_and_the_newest_pair_wins() -> None:
    p = StereoPairer(tolerance=0.002)
    p.add("left", item(1000, tag="L1"))
    p.add("right", item(1000.5, tag="R1"))  # within 2 ms
    p.add("left", item(1033, tag="L2"))
    p.add("right", item(1040, tag="R2"))  # 7 ms off: no pair
    pair = p.take(0.0)
    assert pair is not None and (pair[0].msg, pair[1].msg) == ("L1", "R1")
    assert p.take(0.0) is None  # taken once
    p.add("right", item(1066, tag="R3"))
    p.add("left", item(1066, tag="L3"))
    p.add("left", item(1100, tag="L4"))
    p.add("right", item(1100, tag="R4"))  # replaces the untaken (L3, R3)
    pair = p.take(0.0)
    assert pair is not None and (pair[0].msg, pair[1].msg) == ("L4", "R4")
    assert p.replaced == 1 and p.unpaired == 2  # L2 and R2 never found a partner
    p.add("right", item(1066, tag="late"))  # older than a pair already made
    p.add("left", item(1066, tag="late"))
    assert p.take(0.0) is None and p.pairs == 3


def test_unstamped_images_pair_by_arrival() -> None:
    p = StereoPairer(tolerance=0.002)
    p.add("left", Received(0, 10.000, "L"))
    p.add("right", Received(0, 10.015, "R"))
    pair = p.take(0.0)
    assert pair is not None and (pair[0].msg, pair[1].msg) == ("L", "R")
    p.add("left", Received(0, 11.0, "L"))
    p.add("right", Received(0, 11.1, "R"))
    assert p.take(0.0) is None


@pytest.mark.parametrize("spec", ["ros2:", "ros2:/a", "ros2:a,b", "ros2:/a,/a", "ros2:/a,/b,/c", "ros2:/a, "])
def test_bad_specs_are_one_line(spec: str) -> None:
    with pytest.raises(FrameSourceError) as e:
        parse_ros2_spec(spec)
    assert "\n" not in str(e.value) and "ros2:LEFT,RIGHT" in str(e.value) or "differ" in str(e.value)


@pytest.fixture(scope="module")
def camera_on_ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    d = tmp_path_factory.mktemp("ros2_camera")
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    pairs = render_motion(cam, N, scale=0.5, seed=2)
    save_calibration(d / "calib.yaml", scaled_stereo_camera(cam, 0.5))
    for i, pr in enumerate(pairs):
        cv2.imwrite(str(d / f"pair_{i:02d}_left.png"), pr.left)
        cv2.imwrite(str(d / f"pair_{i:02d}_right.png"), pr.right)
    domain = random.randint(100, 199)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CYCLONEDDS_URI": LOOPBACK_CONFIG, "ROS_DOMAIN_ID": str(domain)}
    ns = f"/cam_{os.getpid()}"
    pub = subprocess.Popen([sys.executable, str(ROOT / "tests" / "rig" / "ros2" / "image_publisher.py"), str(d), ns,
                            "10"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        yield {"calib": str(d / "calib.yaml"), "pairs": pairs, "env": env, "ns": ns, "publisher": pub}
    finally:
        pub.kill()
        pub.communicate()


@pytest.mark.parametrize("suffix", ["", "/compressed"])
def test_track_follows_a_stereo_camera_on_ros2(camera_on_ros2: dict[str, Any], suffix: str) -> None:
    ns = camera_on_ros2["ns"]
    spec = f"ros2:{ns}/left/image_raw{suffix},{ns}/right/image_raw{suffix}"
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "wristmark", "track", "--source", spec, "--frames", "6", "--json",
                        "--calib", camera_on_ros2["calib"], "--axis-hint", "1", "0", "0", "--timeout", "20"],
                       cwd=ROOT, env=camera_on_ros2["env"], capture_output=True, text=True, timeout=120)
    t1 = time.monotonic()
    assert r.returncode == 0, r.stderr
    assert camera_on_ros2["publisher"].poll() is None
    lines = [json.loads(ln) for ln in r.stdout.splitlines() if ln.startswith("{")]
    assert len(lines) == 6 and all(o["ok"] for o in lines), [o.get("reason") for o in lines]
    assert lines[0]["left"] == f"{ns}/left/image_raw{suffix}"
    truth = [p.tip_left for p in camera_on_ros2["pairs"]]
    errors = [min(np.linalg.norm(np.array(o["tip"]) - t) for t in truth) for o in lines]
    assert max(errors) < 0.4e-3, errors  # each frame is one of the published pairs, tracked as from files
    t = [o["t_capture"] for o in lines]
    assert all(b > a for a, b in zip(t, t[1:])) and t0 < t[0] and t[-1] < t1  # stamps on this host's clock


@pytest.mark.parametrize("fields, words", [
    ({"encoding": "bayer_rggb8", "height": 2, "width": 2, "step": 2, "data": bytes(4)}, "not supported"),
    ({"encoding": "bgr8", "height": 4, "width": 4, "step": 12, "data": bytes(10)}, "does not fit"),
])
def test_an_image_topic_s_unsupported_encoding_or_wrong_size_is_one_line(fields: dict[str, Any], words: str) -> None:
    """What a camera topic publishes that we cannot use is a one-line FrameSourceError (the loop
    holds the arm on it like on any frame source error), never a traceback or a wrong image."""
    from wristmark.rig.ros2.image_source import decode
    from wristmark.rig.ros2.messages import Image

    with pytest.raises(FrameSourceError) as e:
        decode(Image(**fields), False, "/cam/left/image_raw")
    assert words in str(e.value) and "\n" not in str(e.value) and "/cam/left/image_raw" in str(e.value)
