"""The ROS 2 messages wristmark speaks, as Cyclone DDS IDL types: written here from the message
definitions (builtin_interfaces, std_msgs, geometry_msgs, sensor_msgs, CRTK's crtk_msgs), so that no ROS
installation is needed. Their DDS type names are ROS 2's (``pkg::msg::dds_::Type_``) and their
serialized bytes are ROS 2's CDR (tests/rig/ros2/test_messages.py compares them with rosbags').

Importing this module needs ``cyclonedds`` (the ``ros2`` extra); :func:`wristmark.rig.ros2.dds_config.
require_cyclonedds` says so in one line first. Units: seconds and nanoseconds, metres, radians.
"""

# no ``from __future__ import annotations``: cyclonedds reads the field types at run time
import math
import struct
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, final

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
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    """std_msgs/String (commands: ``NS/crtk_command`` enable | disable)."""

    data: str = ""


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
class OperatingState(IdlStruct, typename="crtk_msgs::msg::dds_::OperatingState_"):
    """crtk_msgs/OperatingState (CRTK): the arm's ``state`` (ENABLED, DISABLED, PAUSED, FAULT),
    whether it is homed and busy (``NS/operating_state``)."""

    header: Header = field(default_factory=Header)
    state: str = ""
    is_homed: bool = False
    is_busy: bool = False


class _Cdr:
    """Plain CDR (XCDR1) of the image messages, written here so that their pixels are read and
    written as one block of bytes (cyclonedds' generic code handles uint8[] one element at a
    time: seconds for a 1080p image). Offsets count from after the 4-byte encapsulation header."""

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
            raise ValueError("not plain CDR (XCDR1)")
        self.data = memoryview(data)
        self.end = "<" if data[1] == 1 else ">"
        self.pos = 4

    def _align(self, n: int) -> None:
        self.pos += (-(self.pos - 4)) % n

    def u32(self) -> int:
        self._align(4)
        (v,) = struct.unpack_from(self.end + "I", self.data, self.pos)
        self.pos += 4
        return int(v)

    def i32(self) -> int:
        self._align(4)
        (v,) = struct.unpack_from(self.end + "i", self.data, self.pos)
        self.pos += 4
        return int(v)

    def u8(self) -> int:
        v = self.data[self.pos]
        self.pos += 1
        return int(v)

    def blob(self) -> bytes:
        n = self.u32()
        if self.pos + n > len(self.data):
            raise ValueError("CDR sequence runs past the end of the message")
        out = bytes(self.data[self.pos:self.pos + n])
        self.pos += n
        return out

    def string(self) -> str:
        raw = self.blob()
        return raw[:-1].decode("utf-8") if raw.endswith(b"\0") else raw.decode("utf-8")

    def header(self) -> "Header":
        return Header(Time(self.i32(), self.u32()), self.string())


class _CdrWriter:
    """Little-endian plain CDR (XCDR1) with its encapsulation header."""

    def __init__(self) -> None:
        self.parts: list[bytes] = [b"\x00\x01\x00\x00"]
        self.size = 0

    def _align(self, n: int) -> None:
        pad = (-self.size) % n
        if pad:
            self.parts.append(b"\x00" * pad)
            self.size += pad

    def u32(self, v: int, fmt: str = "<I") -> None:
        self._align(4)
        self.parts.append(struct.pack(fmt, v))
        self.size += 4

    def u8(self, v: int) -> None:
        self.parts.append(bytes((v,)))
        self.size += 1

    def blob(self, b: bytes) -> None:
        self.u32(len(b))
        self.parts.append(b)
        self.size += len(b)

    def string(self, s: str) -> None:
        self.blob(s.encode("utf-8") + b"\0")

    def header(self, h: "Header") -> None:
        self.u32(h.stamp.sec, "<i")
        self.u32(h.stamp.nanosec)
        self.string(h.frame_id)

    def getvalue(self) -> bytes:
        return b"".join(self.parts)


@final
@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    """sensor_msgs/Image: raw pixels, ``step`` bytes a row (``data``: bytes)."""

    header: Header = field(default_factory=Header)
    height: t.uint32 = 0
    width: t.uint32 = 0
    encoding: str = ""
    is_bigendian: t.uint8 = 0
    step: t.uint32 = 0
    if TYPE_CHECKING:
        data: bytes = b""
    else:  # uint8[] to cyclonedds (its type object); bytes here (serialize, deserialize below)
        data: t.sequence[t.uint8] = field(default_factory=bytes)

    def serialize(self, buffer: Any = None, endianness: Any = None, use_version_2: bool | None = None) -> bytes:
        """ROS 2's CDR (XCDR1, little endian; anything else: cyclonedds' own code)."""
        if buffer is not None or endianness is not None or use_version_2:
            return super().serialize(buffer=buffer, endianness=endianness, use_version_2=use_version_2)
        w = _CdrWriter()
        w.header(self.header)
        w.u32(self.height)
        w.u32(self.width)
        w.string(self.encoding)
        w.u8(self.is_bigendian)
        w.u32(self.step)
        w.blob(bytes(self.data))
        return w.getvalue()

    @classmethod
    def deserialize(cls, data: bytes, has_header: bool = True, use_version_2: bool | None = None) -> "Image":
        """From ROS 2's CDR (XCDR1, either endianness; anything else: cyclonedds' own code)."""
        if not has_header or use_version_2 is not None or len(data) < 2 or data[1] > 1:
            return super().deserialize(data, has_header=has_header,  # type: ignore[return-value]
                                       use_version_2=use_version_2)
        r = _Cdr(data)
        return cls(r.header(), r.u32(), r.u32(), r.string(), r.u8(), r.u32(), r.blob())


@final
@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    """sensor_msgs/CompressedImage: ``format`` (jpeg, png) and the encoded bytes (``data``)."""

    header: Header = field(default_factory=Header)
    format: str = ""
    if TYPE_CHECKING:
        data: bytes = b""
    else:  # uint8[] to cyclonedds (its type object); bytes here (serialize, deserialize below)
        data: t.sequence[t.uint8] = field(default_factory=bytes)

    def serialize(self, buffer: Any = None, endianness: Any = None, use_version_2: bool | None = None) -> bytes:
        """ROS 2's CDR (XCDR1, little endian; anything else: cyclonedds' own code)."""
        if buffer is not None or endianness is not None or use_version_2:
            return super().serialize(buffer=buffer, endianness=endianness, use_version_2=use_version_2)
        w = _CdrWriter()
        w.header(self.header)
        w.string(self.format)
        w.blob(bytes(self.data))
        return w.getvalue()

    @classmethod
    def deserialize(cls, data: bytes, has_header: bool = True,
                    use_version_2: bool | None = None) -> "CompressedImage":
        """From ROS 2's CDR (XCDR1, either endianness; anything else: cyclonedds' own code)."""
        if not has_header or use_version_2 is not None or len(data) < 2 or data[1] > 1:
            return super().deserialize(data, has_header=has_header,  # type: ignore[return-value]
                                       use_version_2=use_version_2)
        r = _Cdr(data)
        return cls(r.header(), r.string(), r.blob())


MESSAGE_TYPES = (Time, Header, String, Point, Quaternion, Pose, PoseStamped, JointState, Image, CompressedImage,
                 OperatingState)
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
