"""rig.ros2.scene_bridge: every arm of a scene on one participant, under NS/NAME, its poses in
the scene's {w} (frame_id world) and its servo_cp moved into its own {w}; a reader and a writer in
this process, the bridges in this process, on loopback. End to end (servo --scene --ros2 on the
scene's virtual lab): tests/rig/ros2/test_ros2_scene.py."""

from __future__ import annotations

import os
import random
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG

pytestmark = [pytest.mark.network]


def test_each_arm_publishes_under_its_name_in_the_scene_frame_and_takes_its_own_servo_cp(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wristmark.models.robot_params import RobotParams
    from wristmark.rig.recording.run_log import CycleRecord
    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.ros2.scene_bridge import SceneBridges
    from wristmark.rig.targets.live_target import LiveTargets, Workspace

    domain = random.randint(100, 199)
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_CONFIG)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    ns = f"wm_scene_{os.getpid()}"
    bases = {"a": np.eye(4), "b": np.eye(4)}
    bases["a"][:3, 3] = [-0.05, 0.01, 0.0]
    bases["b"][:3, :3] = Rotation.from_rotvec([0.0, 0.0, np.pi]).as_matrix()
    bases["b"][:3, 3] = [0.05, -0.01, 0.002]
    R = Rotation.from_rotvec([0.1, -0.4, 0.3]).as_matrix()
    tip = {"a": np.array([0.08, 0.001, 0.147]), "b": np.array([0.075, -0.002, 0.15])}
    dp = DomainParticipant(domain)
    qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(64))
    readers = {n: DataReader(dp, Topic(dp, M.topic_name(f"/{ns}/{n}/measured_cp"), M.PoseStamped), qos)
               for n in bases}
    writer = DataWriter(dp, Topic(dp, M.topic_name(f"/{ns}/b/servo_cp"), M.PoseStamped), qos)
    store = LiveTargets(Workspace.around(tip["b"], (0.2, 0.2, 0.2)), timeout=10.0)
    z3, psi = np.zeros(3), np.zeros(6)
    bridges = SceneBridges(ns, {n: RobotParams() for n in bases}, bases, {"b": store})
    try:
        report = bridges.report()
        assert {n: r["published"][0] for n, r in report.items()} == {n: f"/{ns}/{n}/measured_cp" for n in bases}
        assert report["b"]["subscribed"] == [f"/{ns}/b/servo_cp"] and report["a"]["subscribed"] == []
        assert all(b.participant is bridges.participant for b in bridges.bridges.values())  # one participant
        time.sleep(1.0)  # discovery
        for n in bases:
            bridges.on_cycle(n, CycleRecord(1.0, "servo", z3, z3, tip[n], z3, z3, psi, psi, True, False, 1.0, 1.0,
                                            t_wall=1.0, R_est=R))
        goal = bases["b"][:3, :3] @ tip["b"] + bases["b"][:3, 3] + [0.0, 0.0, 0.003]  # 3 mm up in the scene's {w}
        writer.write(M.pose_stamped(time.time(), "world", goal.tolist()))
        got: dict[str, list[object]] = {n: [] for n in bases}
        t_end = time.monotonic() + 5.0
        while time.monotonic() < t_end and not (all(got.values()) and store.newest()[0] is not None):
            for n, r in readers.items():
                got[n] += [m for m in r.take(N=64) if hasattr(m, "pose")]
            time.sleep(0.02)
    finally:
        bridges.close()
    for n, B in bases.items():
        assert len(got[n]) == 1, got
        msg = got[n][0]
        pos, q = msg.pose.position, msg.pose.orientation  # type: ignore[attr-defined]
        assert msg.header.frame_id == "world"  # type: ignore[attr-defined]
        np.testing.assert_allclose([pos.x, pos.y, pos.z], B[:3, :3] @ tip[n] + B[:3, 3], atol=1e-9)
        np.testing.assert_allclose(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), B[:3, :3] @ R, atol=1e-9)
    target, _ = store.newest()
    assert target is not None  # b's servo_cp, in b's own {w}: 3 mm up there too (b turned about z only)
    np.testing.assert_allclose(target.p, tip["b"] + [0.0, 0.0, 0.003], atol=1e-9)
