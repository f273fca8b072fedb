"""The ROS 2 messages as Cyclone DDS IDL types (rig/ros2/messages.py): the same bytes as ROS 2's
CDR (rosbags' ROS2_HUMBLE typestore; CRTK's OperatingState registered from its .msg text) for every
type, ROS 2's DDS type and topic names, and a round trip through the bytes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from wristmark.rig.ros2 import messages as M

TS = get_typestore(Stores.ROS2_HUMBLE)
CRTK_OPERATING_STATE_MSG = """\
# crtk_msgs/msg/OperatingState.msg (CRTK)
std_msgs/Header header
string state  # ENABLED, DISABLED, PAUSED, FAULT
bool is_homed
bool is_busy
"""
TS.register(get_types_from_msg(CRTK_OPERATING_STATE_MSG, "crtk_msgs/msg/OperatingState"))  # not built into rosbags


def ros(name: str) -> Any:
    return TS.types[name]


def ros_header(sec: int, nanosec: int, frame: str) -> Any:
    return ros("std_msgs/msg/Header")(ros("builtin_interfaces/msg/Time")(sec, nanosec), frame)


HEADER = M.Header(M.Time(1_700_000_123, 456_789_012), "world")
ROS_HEADER = ros_header(1_700_000_123, 456_789_012, "world")
PIXELS = bytes(range(256)) * 3  # 16 x 16 x 3


def cases() -> list[tuple[Any, Any]]:
    """(our message, rosbags' message) pairs with the same contents, every type (odd lengths
    of strings and sequences, so that the CDR alignment padding is exercised)."""
    P, Q = ros("geometry_msgs/msg/Point"), ros("geometry_msgs/msg/Quaternion")
    pose = M.Pose(M.Point(0.0776, -0.001, 0.147), M.Quaternion(0.1, -0.2, 0.3, 0.9273618495495703))
    ros_pose = ros("geometry_msgs/msg/Pose")(P(0.0776, -0.001, 0.147), Q(0.1, -0.2, 0.3, 0.9273618495495703))
    names = ["phi", "z", "beta1", "delta1", "beta2x", "delta2"]
    js = M.JointState(M.Header(M.Time(3, 7), "a"), names, [0.1, 0.002, 0.3, -0.4, 0.5, 0.6], [1.5], [])
    ros_js = ros("sensor_msgs/msg/JointState")(ros_header(3, 7, "a"), names,
                                               np.array([0.1, 0.002, 0.3, -0.4, 0.5, 0.6]), np.array([1.5]),
                                               np.array([], float))
    return [
        (M.Time(-5, 999_999_999), ros("builtin_interfaces/msg/Time")(-5, 999_999_999)),
        (HEADER, ROS_HEADER),
        (M.Header(M.Time(0, 0), ""), ros_header(0, 0, "")),
        (M.String("enable"), ros("std_msgs/msg/String")("enable")),
        (M.String(""), ros("std_msgs/msg/String")("")),
        (M.Point(1.0, 2.0, 3.0), P(1.0, 2.0, 3.0)),
        (M.Quaternion(), Q(0.0, 0.0, 0.0, 1.0)),
        (pose, ros_pose),
        (M.PoseStamped(HEADER, pose), ros("geometry_msgs/msg/PoseStamped")(ROS_HEADER, ros_pose)),
        (M.PoseStamped(M.Header(M.Time(1, 2), "wristmark_w"), pose),
         ros("geometry_msgs/msg/PoseStamped")(ros_header(1, 2, "wristmark_w"), ros_pose)),
        (js, ros_js),
        (M.JointState(), ros("sensor_msgs/msg/JointState")(ros_header(0, 0, ""), [], *[np.array([], float)] * 3)),
        (M.Image(HEADER, 16, 16, "rgb8", 0, 48, PIXELS),
         ros("sensor_msgs/msg/Image")(ROS_HEADER, 16, 16, "rgb8", 0, 48, np.frombuffer(PIXELS, np.uint8))),
        (M.Image(M.Header(M.Time(1, 1), "left"), 1, 3, "mono8", 1, 3, b"\x01\x02\x03"),
         ros("sensor_msgs/msg/Image")(ros_header(1, 1, "left"), 1, 3, "mono8", 1, 3,
                                      np.array([1, 2, 3], np.uint8))),
        (M.OperatingState(HEADER, "ENABLED", True, False),
         ros("crtk_msgs/msg/OperatingState")(ROS_HEADER, "ENABLED", True, False)),
        (M.OperatingState(M.Header(M.Time(1, 2), ""), "FAULT", False, True),
         ros("crtk_msgs/msg/OperatingState")(ros_header(1, 2, ""), "FAULT", False, True)),
        (M.CompressedImage(HEADER, "jpeg", b"\xff\xd8\xff\xe0JFIF\xff\xd9"),
         ros("sensor_msgs/msg/CompressedImage")(ROS_HEADER, "jpeg",
                                                np.frombuffer(b"\xff\xd8\xff\xe0JFIF\xff\xd9", np.uint8))),
    ]


@pytest.mark.parametrize("ours, theirs", cases(), ids=lambda x: type(x).__name__)
def test_the_bytes_are_ros2_cdr(ours: Any, theirs: Any) -> None:
    name = M.ROS_NAMES[type(ours)]
    expected = bytes(TS.serialize_cdr(theirs, name))
    assert ours.serialize() == expected
    back = type(ours).deserialize(expected)
    assert back.serialize() == expected


def test_every_type_is_covered_and_named_as_ros2_names_it() -> None:
    assert {type(o) for o, _ in cases()} == set(M.MESSAGE_TYPES)
    for cls in M.MESSAGE_TYPES:
        assert M.ROS_NAMES[cls] in TS.types
        pkg, _, name = M.ROS_NAMES[cls].split("/")
        assert cls.__idl_typename__ == f"{pkg}::msg::dds_::{name}_"


def test_topic_names_and_stamps() -> None:
    assert M.topic_name("/arm/measured_cp") == "rt/arm/measured_cp"
    assert M.topic_name("measured_cp") == "rt/measured_cp"
    t = M.Time.of_seconds(12.000000001)
    assert (t.sec, t.nanosec) == (12, 1) and abs(t.seconds() - 12.000000001) < 1e-12
    ps = M.pose_stamped(1.5, "w", [1.0, 2.0, 3.0])
    assert ps.header.frame_id == "w" and ps.pose.orientation.w == 1.0 and ps.header.stamp.nanosec == 500_000_000


@pytest.mark.parametrize("ours, theirs", [c for c in cases() if isinstance(c[0], M.Image | M.CompressedImage)],
                         ids=lambda x: type(x).__name__)
def test_the_image_types_own_cdr_agrees_with_cyclonedds_and_reads_big_endian(ours: Any, theirs: Any) -> None:
    """Image and CompressedImage write and read their pixels as one block (their own CDR code):
    the same bytes as cyclonedds' generic code, and rosbags' big-endian CDR read back."""
    generic = type(ours).__idl__.serialize(ours)
    assert ours.serialize() == generic
    big = bytes(TS.serialize_cdr(theirs, M.ROS_NAMES[type(ours)], little_endian=False))
    assert big[:2] == b"\x00\x00"
    back = type(ours).deserialize(big)
    assert back == type(ours).deserialize(generic) and isinstance(back.data, bytes)
    assert back.serialize() == ours.serialize()
