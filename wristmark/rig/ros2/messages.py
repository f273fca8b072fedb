"""The ROS 2 messages wristmark speaks, as Cyclone DDS IDL types: written here from the message
definitions (builtin_interfaces, std_msgs, geometry_msgs, sensor_msgs), so that no ROS
installation is needed. Their DDS type names are ROS 2's (``pkg::msg::dds_::Type_``) and their
serialized bytes are ROS 2's CDR (tests/rig/ros2/test_messages.py compares them with rosbags').

Importing this module needs ``cyclonedds`` (the ``ros2`` extra); :func:`wristmark.rig.ros2.dds_config.
require_cyclonedds` says so in one line first. Units: seconds and nanoseconds, metres, radians.
"""

# no ``from __future__ import annotations``: cyclonedds reads the field types at run time
import math
from dataclasses import dataclass, field
from typing import final

import cyclonedds.idl.types as t
from cyclonedds.idl import IdlStruct


@final
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    """builtin_interfaces/Time: seconds and nanoseconds (0 <= nanosec < 1e9)."""

    sec: t.int32 = 0
    nanosec: t.uint32 = 0

    @classmethod
    def of_seconds(cls, s: float) -> "Time":
        """The time ``s`` [s] (>= 0 after the epoch of its clock), to the nanosecond."""
        ns = int(round(s * 1e9))
        return cls(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def seconds(self) -> float:
        """The time in seconds."""
        return self.sec + 1e-9 * self.nanosec


@final
@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    """std_msgs/Header: the stamp and the frame the data are expressed in."""

    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@final
@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    """geometry_msgs/Point [m]."""

    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@final
@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    """geometry_msgs/Quaternion (x, y, z, w; identity by default)."""

    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0
    w: t.float64 = 1.0


@final
@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    """geometry_msgs/Pose: position [m] and orientation of a frame in its parent."""

    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@final
@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    """geometry_msgs/PoseStamped: a pose in ``header.frame_id`` at ``header.stamp``."""

    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@final
@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    """sensor_msgs/JointState: named joints' positions (and velocities, efforts; may be empty)."""

    header: Header = field(default_factory=Header)
    name: t.sequence[str] = field(default_factory=list)  # type: ignore[type-arg, assignment]  # cyclonedds' run-time types
    position: t.sequence[t.float64] = field(default_factory=list)  # type: ignore[type-arg, assignment]  # cyclonedds' run-time types
    velocity: t.sequence[t.float64] = field(default_factory=list)  # type: ignore[type-arg, assignment]  # cyclonedds' run-time types
    effort: t.sequence[t.float64] = field(default_factory=list)  # type: ignore[type-arg, assignment]  # cyclonedds' run-time types


@final
@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    """sensor_msgs/Image: raw pixels, ``step`` bytes a row."""

    header: Header = field(default_factory=Header)
    height: t.uint32 = 0
    width: t.uint32 = 0
    encoding: str = ""
    is_bigendian: t.uint8 = 0
    step: t.uint32 = 0
    data: t.sequence[t.uint8] = field(default_factory=bytes)  # type: ignore[type-arg, assignment]  # cyclonedds' run-time types


@final
@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    """sensor_msgs/CompressedImage: ``format`` (jpeg, png) and the encoded bytes."""

    header: Header = field(default_factory=Header)
    format: str = ""
    data: t.sequence[t.uint8] = field(default_factory=bytes)  # type: ignore[type-arg, assignment]  # cyclonedds' run-time types


MESSAGE_TYPES = (Time, Header, Point, Quaternion, Pose, PoseStamped, JointState, Image, CompressedImage)
ROS_NAMES = {cls: cls.__idl_typename__.replace("::dds_::", "::").replace("::", "/").rstrip("_")
             for cls in MESSAGE_TYPES}  # e.g. geometry_msgs/msg/PoseStamped


def topic_name(name: str) -> str:
    """The DDS topic of the ROS 2 topic ``name`` (``/arm/measured_cp`` -> ``rt/arm/measured_cp``)."""
    return "rt/" + name.strip("/")


def pose_stamped(stamp_s: float, frame_id: str, p: list[float], q: list[float] | None = None) -> "PoseStamped":
    """A PoseStamped at ``stamp_s`` [s] of the position ``p`` [m] and quaternion ``q`` (x, y, z, w;
    None: identity) in ``frame_id``."""
    x, y, z, w = q if q is not None else (0.0, 0.0, 0.0, 1.0)
    return PoseStamped(Header(Time.of_seconds(stamp_s), frame_id),
                       Pose(Point(*map(float, p)), Quaternion(float(x), float(y), float(z), float(w))))


def finite(values: list[float]) -> bool:
    """Every value is a finite number."""
    return all(isinstance(v, float | int) and math.isfinite(v) for v in values)
