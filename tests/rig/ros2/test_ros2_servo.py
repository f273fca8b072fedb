"""`wristmark servo --ros2 [NS]`: its options fail in one line before any motion, and without
cyclonedds --ros2 is one clear line while import wristmark still works. The loop on a ROS 2
graph end to end: tests/rig/ros2/test_ros2_steering.py."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG

pytestmark = [pytest.mark.network]

ROOT = Path(__file__).resolve().parents[3]


def env(domain: int) -> dict[str, str]:
    e = {**os.environ, "PYTHONPATH": str(ROOT), "CYCLONEDDS_URI": LOOPBACK_CONFIG, "ROS_DOMAIN_ID": str(domain)}
    return e


def no_probe_controller(tmp: Path) -> Path:
    text = (ROOT / "wristmark" / "configs" / "controller.yaml").read_text()
    out = tmp / "controller.yaml"
    out.write_text(re.sub(r"play_probe: true", "play_probe: false", text))
    return out


def test_without_cyclonedds_ros2_is_one_clear_line_and_wristmark_imports(tmp_path: Path) -> None:
    blocker = tmp_path / "sitecustomize.py"  # cyclonedds made unimportable in the child
    blocker.write_text("import sys\nclass _Block:\n    def find_spec(self, name, path=None, target=None):\n"
                       "        if name.split('.')[0] == 'cyclonedds':\n"
                       "            raise ModuleNotFoundError(\"No module named 'cyclonedds'\")\n"
                       "sys.meta_path.insert(0, _Block())\n")
    e = {**env(0), "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}"}
    r = subprocess.run([sys.executable, "-c", "import wristmark, wristmark.rig, wristmark.cli.servo; print('ok')"],
                       env=e, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr
    r = subprocess.run([sys.executable, "-m", "wristmark", "servo", "--ros2", "--sensor", "truth-noise",
                        "--no-progress"], cwd=ROOT, env=e, capture_output=True, text=True, timeout=60)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "cyclonedds" in lines[0] and "wristmark[ros2]" in lines[0]


@pytest.mark.parametrize("args, words", [
    (["--target", "ros2"], ["--target ros2 needs --ros2"]),
    (["--ros2", "1bad/ns"], ["--ros2", "namespace"]),
    (["--ros2", "a b"], ["--ros2", "namespace"]),
    (["--actuator", "ros2:/arm"], ["--actuator ros2:NS needs --camera"]),
    (["--actuator", "serial:/dev/x", "--camera", "ros2:/l,/r"], ["--actuator must be ros2:NS"]),
    (["--actuator", "ros2:9x", "--camera", "ros2:/l,/r"], ["--actuator", "namespace"]),
    (["--actuator", "ros2:/arm", "--camera", "ros2:/l,/r", "--ros2", "arm"], ["--ros2 NS must differ"]),
    (["--actuator", "ros2:/arm", "--serial", "/dev/null"], ["not allowed with argument"]),
])
def test_bad_ros2_options_are_one_line_before_any_motion(args: list[str], words: list[str]) -> None:
    r = subprocess.run([sys.executable, "-m", "wristmark", "servo", "--sensor", "truth-noise", "--no-progress", *args],
                       cwd=ROOT, env=env(0), capture_output=True, text=True, timeout=60)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert all(w in lines[0] for w in words), lines[0]


def test_servo_cp_is_validated_before_it_reaches_the_targets(monkeypatch: pytest.MonkeyPatch) -> None:
    """A wrong frame_id, a non-finite position or a zero quaternion is counted and dropped with a
    warning; a good message is offered (the bridge in this process, on loopback)."""
    import io

    import numpy as np

    from wristmark.models.robot_params import RobotParams
    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.ros2.bridge import Ros2Bridge
    from wristmark.rig.targets.live_target import LiveTargets, Workspace

    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_CONFIG)
    monkeypatch.setenv("ROS_DOMAIN_ID", "201")
    warn = io.StringIO()
    targets = LiveTargets(Workspace.around(np.array([0.08, 0.0, 0.15])), warn=warn)
    with Ros2Bridge("/unit/", RobotParams(), targets) as bridge:
        assert bridge.topic("servo_cp") == "/unit/servo_cp"
        bad = [M.pose_stamped(1.0, "camera", [0.08, 0.0, 0.15]),
               M.pose_stamped(1.0, "world", [0.08, float("nan"), 0.15]),
               M.pose_stamped(1.0, "world", [0.08, 0.0, 0.15], [0.0, 0.0, 0.0, 0.0])]
        assert not any(bridge.offer(m) for m in bad)
        assert bridge.offer(M.pose_stamped(2.0, "world", [0.081, 0.0, 0.15], [0.0, 0.0, 0.0, 1.0]))
    assert targets.counts.dropped == 3 and targets.counts.received == 1
    assert len(warn.getvalue().splitlines()) == 3 and "frame_id 'camera'" in warn.getvalue()


def test_the_bridge_publishes_the_marker_pose_beside_the_tip(monkeypatch: pytest.MonkeyPatch) -> None:
    """A cycle with a measured marker: NS/marker/measured_cp carries its pose in {w} (frame_id
    world, the position within 1e-9 m) with the tip's stamp; a cycle without one publishes neither
    (a reader in this process, the bridge in this process, on loopback)."""
    import random
    import time

    import numpy as np
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from scipy.spatial.transform import Rotation

    from wristmark.models.robot_params import RobotParams
    from wristmark.rig.recording.run_log import CycleRecord
    from wristmark.rig.ros2 import messages as M
    from wristmark.rig.ros2.bridge import Ros2Bridge

    domain = random.randint(100, 199)
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK_CONFIG)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    ns = f"wm_marker_{os.getpid()}"
    dp = DomainParticipant(domain)
    qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(64))
    readers = {n: DataReader(dp, Topic(dp, M.topic_name(f"/{ns}/{n}"), M.PoseStamped), qos)
               for n in ("measured_cp", "marker/measured_cp")}
    R = Rotation.from_rotvec([0.1, -0.4, 0.3]).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [0.0712345678912, -0.00312345678, 0.131234567891]
    tip = T[:3, 3] + R @ [0.0, 0.0, 0.012]
    z3, psi = np.zeros(3), np.zeros(6)

    def record(t: float, measured: bool) -> CycleRecord:
        return CycleRecord(t, "servo", z3, z3, tip if measured else None, z3, z3, psi, psi, measured, False, 1.0,
                           1.0, t_wall=t, R_est=R if measured else None, T_marker_est=T if measured else None)

    with Ros2Bridge(ns, RobotParams()) as bridge:
        assert f"/{ns}/marker/measured_cp" in bridge.report()["published"]
        time.sleep(1.0)  # discovery
        bridge.on_cycle(record(100.0, False), None)
        time.sleep(0.2)
        bridge.on_cycle(record(100.1, True), None)
    got: dict[str, list[object]] = {n: [] for n in readers}
    t_end = time.monotonic() + 5.0
    while time.monotonic() < t_end and not all(got.values()):
        for n, r in readers.items():
            got[n] += [m for m in r.take(N=64) if hasattr(m, "pose")]
        time.sleep(0.02)
    time.sleep(0.2)
    for n, r in readers.items():
        got[n] += [m for m in r.take(N=64) if hasattr(m, "pose")]
    assert len(got["measured_cp"]) == len(got["marker/measured_cp"]) == 1, got
    tip_msg, marker_msg = got["measured_cp"][0], got["marker/measured_cp"][0]
    for msg, p in ((tip_msg, tip), (marker_msg, T[:3, 3])):
        pos, q = msg.pose.position, msg.pose.orientation  # type: ignore[attr-defined]
        assert msg.header.frame_id == "world"  # type: ignore[attr-defined]
        assert np.abs(np.array([pos.x, pos.y, pos.z]) - p).max() < 1e-9
        assert np.abs(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix() - R).max() < 1e-9
    assert marker_msg.header.stamp == tip_msg.header.stamp  # type: ignore[attr-defined]
