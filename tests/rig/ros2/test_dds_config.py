"""The DDS configuration (rig/ros2/dds_config.py): loopback only when CYCLONEDDS_URI is unset, a
user's own configuration used as given, and a participant really opened with it (a fresh process,
so that the configuration is the one read by the first participant)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from wristmark.models.errors import InputError
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG, domain_id, ensure_loopback

pytestmark = [pytest.mark.network]

ROOT = Path(__file__).resolve().parents[3]


def test_the_loopback_configuration_when_none_is_given() -> None:
    for env in ({}, {"CYCLONEDDS_URI": ""}, {"CYCLONEDDS_URI": "  "}):
        assert ensure_loopback(env) == LOOPBACK_CONFIG
        assert env["CYCLONEDDS_URI"] == LOOPBACK_CONFIG
    for needle in ('<NetworkInterface name="lo"/>', "<AllowMulticast>false</AllowMulticast>",
                   '<Peer address="127.0.0.1"/>', "<ParticipantIndex>auto</ParticipantIndex>"):
        assert needle in LOOPBACK_CONFIG


def test_a_users_configuration_is_used_as_given() -> None:
    env = {"CYCLONEDDS_URI": "file:///etc/lab/cyclonedds.xml"}
    assert ensure_loopback(env) == "file:///etc/lab/cyclonedds.xml"
    assert env == {"CYCLONEDDS_URI": "file:///etc/lab/cyclonedds.xml"}


def test_the_domain_is_ros_domain_id() -> None:
    assert domain_id({}) == 0 and domain_id({"ROS_DOMAIN_ID": "42"}) == 42
    for bad in ("x", "-1", "233"):
        with pytest.raises(InputError):
            domain_id({"ROS_DOMAIN_ID": bad})


def test_a_participant_opened_without_a_configuration_is_on_loopback() -> None:
    """In a fresh process without CYCLONEDDS_URI: the configuration in force is the loopback one,
    and a writer and a reader of that participant find each other."""
    code = """
import os, time
from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG, open_participant
assert "CYCLONEDDS_URI" not in os.environ
dp = open_participant()
assert os.environ["CYCLONEDDS_URI"] == LOOPBACK_CONFIG
from cyclonedds.topic import Topic
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from wristmark.rig.ros2.messages import pose_stamped, PoseStamped
topic = Topic(dp, "rt/wristmark_test/config", PoseStamped)
w, r = DataWriter(dp, topic), DataReader(dp, topic)
deadline = time.monotonic() + 10
got = []
while not got and time.monotonic() < deadline:
    w.write(pose_stamped(1.0, "w", [1.0, 2.0, 3.0]))
    time.sleep(0.05)
    got = r.take()
assert got and got[0].pose.position.z == 3.0
print("ok")
"""
    env = {k: v for k, v in os.environ.items() if k != "CYCLONEDDS_URI"}
    env["PYTHONPATH"] = str(ROOT)
    env["ROS_DOMAIN_ID"] = "77"  # away from any other test's participants
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr
