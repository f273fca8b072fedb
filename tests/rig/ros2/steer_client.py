"""A ROS 2 node that knows only the message definitions (wristmark.rig.ros2.messages, Cyclone
DDS): it listens to NS/measured_cp, NS/marker/measured_cp, NS/measured_js and NS/setpoint_js
(the tip in the marker's frame of the marker message with the tip's stamp) and steers the tip through
NS/servo_cp; run by tests/rig/ros2/test_ros2_servo.py as its own process (CYCLONEDDS_URI and
ROS_DOMAIN_ID from the test). Usage: steer_client.py NS DX_MM DZ_MM HOLD_S. Prints one JSON
object: what it sent and what it received (its own monotonic clock [s], positions [m])."""

from __future__ import annotations

import json
import math
import os
import sys
import time

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from wristmark.rig.ros2.messages import JointState, PoseStamped, pose_stamped, topic_name


def main() -> None:
    ns, dx, dz, hold = sys.argv[1], float(sys.argv[2]) / 1000, float(sys.argv[3]) / 1000, float(sys.argv[4])
    assert "127.0.0.1" in os.environ["CYCLONEDDS_URI"]  # the test's loopback configuration
    dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))
    qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(10))
    cp = DataReader(dp, Topic(dp, topic_name(f"{ns}/measured_cp"), PoseStamped), qos)
    marker_cp = DataReader(dp, Topic(dp, topic_name(f"{ns}/marker/measured_cp"), PoseStamped), qos)
    js = DataReader(dp, Topic(dp, topic_name(f"{ns}/measured_js"), JointState), qos)
    sp = DataReader(dp, Topic(dp, topic_name(f"{ns}/setpoint_js"), JointState), qos)
    servo_cp = DataWriter(dp, Topic(dp, topic_name(f"{ns}/servo_cp"), PoseStamped), qos)
    t0 = time.monotonic()
    measured: list[tuple[float, list[float]]] = []
    tips: dict[tuple[int, int], list[float]] = {}  # the tip by its stamp
    markers: dict[tuple[int, int], tuple[list[float], list[float]]] = {}  # the marker (position, q) by stamp
    sent: list[tuple[float, list[float]]] = []
    names: dict[str, list[str]] = {}
    joints = {"measured_js": 0, "setpoint_js": 0}
    start: list[float] | None = None
    bad_sent = False
    last_rx = time.monotonic()
    while time.monotonic() - t0 < 90:
        now = time.monotonic()
        for msg in cp.take(N=64):
            p = msg.pose.position
            measured.append((now - t0, [p.x, p.y, p.z]))
            assert msg.header.frame_id == "world"
            tips[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = [p.x, p.y, p.z]
            last_rx = now
        for msg in marker_cp.take(N=64):
            p, q = msg.pose.position, msg.pose.orientation
            assert msg.header.frame_id == "world"
            markers[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = ([p.x, p.y, p.z], [q.x, q.y, q.z, q.w])
        for key, reader in (("measured_js", js), ("setpoint_js", sp)):
            for msg in reader.take(N=64):
                joints[key] += 1
                names[key] = list(msg.name)
        if start is None and measured:
            start, t_start = measured[-1][1], now
        if start is not None:
            if not bad_sent:  # counted and dropped by the loop, never a motion
                servo_cp.write(pose_stamped(time.time(), "camera", [start[0] + 0.02, start[1], start[2]]))
                servo_cp.write(pose_stamped(time.time(), "world", [math.nan, start[1], start[2]]))
                bad_sent = True
            a = [start[0] + dx, start[1], start[2]]
            target = a if now - t_start < hold else [a[0], a[1], a[2] + dz]
            servo_cp.write(pose_stamped(time.time(), "world", target))
            sent.append((now - t0, target))
            if now - last_rx > 2.0:  # the loop ended
                break
        time.sleep(0.04)
    tip_in_marker = []  # R_marker^T (tip - marker origin) [m], for each marker message with a tip of its stamp
    for stamp, (m, (x, y, z, w)) in markers.items():
        if stamp in tips:
            R = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
            d = [tips[stamp][i] - m[i] for i in range(3)]
            tip_in_marker.append([sum(R[i][j] * d[i] for i in range(3)) for j in range(3)])
    print(json.dumps({"measured": measured, "sent": sent, "joints": joints, "names": names,
                      "markers": len(markers), "tip_in_marker": tip_in_marker,
                      "loop_modules": sorted(m for m in sys.modules
                                             if m.startswith(("wristmark.rig.loop", "wristmark.rig.targets",
                                                              "wristmark.sim", "wristmark.cli")))}))


if __name__ == "__main__":
    main()
