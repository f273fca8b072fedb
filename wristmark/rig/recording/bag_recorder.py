"""Record a tracking or servo run as a ROS 2 bag in MCAP (docs/design.md "Recording"), with rosbags.

Topics: ``/stereo/left/image_raw`` and ``/stereo/right/image_raw`` (``sensor_msgs/msg/Image``
bgr8 or mono8, or ``sensor_msgs/msg/CompressedImage`` jpeg with ``jpeg=True``, frame ids
``left_camera``/``right_camera``); ``/wristmark/marker_pose`` and ``/wristmark/tip``
(``geometry_msgs/msg/PoseStamped``: the pose of {wm}, and the tip with {wm}'s orientation, in
frame ``left_camera``; with a ``world_T_left`` a second message in frame ``world`` on the same
topic); ``/wristmark/actuators`` (``sensor_msgs/msg/JointState``, names phi, d, s1a, s1b, s2a,
s2b for the reference arm, the robot file's actuator names for another, positions in rad and m:
one message with ``frame_id`` ``commanded`` and one ``measured``). Several arms in one view
(``servo --scene --record``): the images once, and each arm's poses and actuators on its own
topics ``/wristmark/NAME/marker_pose``, ``/wristmark/NAME/tip``, ``/wristmark/NAME/actuators``
(``world``: the scene's {w}).

Every message is stamped (header and log time) with the frame's capture time mapped from the
host's ``time.monotonic()`` to the wall clock once, when the recorder opens:
``stamp = t_capture + (time.time() - time.monotonic())`` [s] (ROS tools expect wall-clock
stamps); the bag source maps them back (cvs.sources.bag).

rosbags writes a bag directory; the recorder writes it next to FILE.mcap
(``FILE.mcap.partial/``) and moves its one MCAP file to FILE.mcap on ``close()``. An existing
FILE.mcap (or a leftover partial directory) is never overwritten.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.cvs.sources.frames import StereoFrame
from wristmark.cvs.sources.ros_image_msgs import COMPRESSED, IMAGE, header_msg, image_msg, typestore
from wristmark.models.errors import InputError

Array = NDArray[np.float64]
LEFT_TOPIC, RIGHT_TOPIC = "/stereo/left/image_raw", "/stereo/right/image_raw"
POSE_TOPIC, TIP_TOPIC, ACTUATOR_TOPIC = "/wristmark/marker_pose", "/wristmark/tip", "/wristmark/actuators"
ACTUATOR_NAMES = ("phi", "d", "s1a", "s1b", "s2a", "s2b")
POSE_TYPE, JOINT_TYPE = "geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/JointState"


def arm_topics(arm: str | None) -> tuple[str, str, str]:
    """(marker pose, tip, actuators) topics of arm ``arm`` of a scene (None: the one arm)."""
    if arm is None:
        return POSE_TOPIC, TIP_TOPIC, ACTUATOR_TOPIC
    return f"/wristmark/{arm}/marker_pose", f"/wristmark/{arm}/tip", f"/wristmark/{arm}/actuators"


class BagRecorder:
    """Writes the topics of the module docstring to ``path`` (must end in .mcap and not exist).

    jpeg: images as CompressedImage (JPEG at ``jpeg_quality``) instead of raw bgr8;
    world_T_left: 4x4 pose of {ll} in {w} [m] (poses are then also written in ``world``);
    actuator_names: the JointState names of the actuators, in the arm's order (the reference arm's
    by default; any arm's from models.arm_spec.actuator_names); arms: several arms' actuator names
    by arm (their topics per arm, :func:`arm_topics`; ``world_T_left`` then in the scene's {w})."""

    def __init__(self, path: str | Path, jpeg: bool = False, jpeg_quality: int = 90,
                 world_T_left: Array | None = None, actuator_names: tuple[str, ...] = ACTUATOR_NAMES,
                 arms: Mapping[str, tuple[str, ...]] | None = None) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.actuator_names = tuple(actuator_names)
        self.arm_actuators: dict[str | None, tuple[str, ...]] = (
            {n: tuple(a) for n, a in arms.items()} if arms else {None: self.actuator_names})
        self.path = Path(path)
        if self.path.suffix.lower() != ".mcap":
            raise InputError(f"{self.path}: a recording must be an .mcap file")
        self._partial = self.path.with_name(self.path.name + ".partial")
        if self.path.exists():
            raise InputError(f"{self.path} exists already: not overwriting a recording (remove it or pick another)")
        if self._partial.exists():
            raise InputError(f"{self._partial} exists (left by an interrupted recording): remove it first")
        if not self.path.parent.is_dir():
            raise InputError(f"{self.path.parent}: folder for the recording does not exist")
        if not 1 <= int(jpeg_quality) <= 100:
            raise InputError(f"JPEG quality must be in 1..100, got {jpeg_quality}")
        self.jpeg_quality = int(jpeg_quality) if jpeg else None
        self.world_T_left = None if world_T_left is None else np.asarray(world_T_left, float).reshape(4, 4)
        self._clock_offset = time.time() - time.monotonic()  # wall - monotonic [s]
        self._store = typestore()
        self._writer = Writer(self._partial, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        image_type = COMPRESSED if jpeg else IMAGE
        self._conn: dict[str, tuple[Any, str]] = {}
        topics = [(LEFT_TOPIC, image_type), (RIGHT_TOPIC, image_type)]
        for arm in self.arm_actuators:
            pose, tip, actuators = arm_topics(arm)
            topics += [(pose, POSE_TYPE), (tip, POSE_TYPE), (actuators, JOINT_TYPE)]
        for topic, msgtype in topics:
            self._conn[topic] = (self._writer.add_connection(topic, msgtype, typestore=self._store), msgtype)
        self.messages = 0
        self._closed = False

    def stamp_ns(self, t_capture: float) -> int:
        """The bag stamp [ns] of a host monotonic time [s]."""
        return int(round((t_capture + self._clock_offset) * 1e9))

    def _write(self, topic: str, msg: Any, t_ns: int) -> None:
        conn, msgtype = self._conn[topic]
        self._writer.write(conn, t_ns, self._store.serialize_cdr(msg, msgtype))
        self.messages += 1

    def write_frame(self, frame: StereoFrame) -> None:
        """Both images of a frame, stamped with its capture time."""
        t = self.stamp_ns(frame.t_capture)
        self._write(LEFT_TOPIC, image_msg(self._store, frame.left, t, "left_camera", self.jpeg_quality), t)
        self._write(RIGHT_TOPIC, image_msg(self._store, frame.right, t, "right_camera", self.jpeg_quality), t)

    def _pose(self, t_ns: int, frame_id: str, T: Array) -> Any:
        types = self._store.types
        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
            orientation=types["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w)),
        )
        return types[POSE_TYPE](header=header_msg(self._store, t_ns, frame_id), pose=pose)

    def write_pose(self, t_capture: float, T_left_marker: Array, tip_left: Array, arm: str | None = None) -> None:
        """The marker pose (4x4 of {wm} in {ll} [m]) and the tip (in {ll} [m], with {wm}'s
        orientation) of the frame captured at ``t_capture`` [s, monotonic] (of arm ``arm``)."""
        t = self.stamp_ns(t_capture)
        pose_topic, tip_topic, _ = arm_topics(arm)
        T_marker = np.asarray(T_left_marker, float).reshape(4, 4)
        T_tip = T_marker.copy()
        T_tip[:3, 3] = np.asarray(tip_left, float).reshape(3)
        frames = [("left_camera", np.eye(4))]
        if self.world_T_left is not None:
            frames.append(("world", self.world_T_left))
        for frame_id, T_frame_left in frames:
            self._write(pose_topic, self._pose(t, frame_id, T_frame_left @ T_marker), t)
            self._write(tip_topic, self._pose(t, frame_id, T_frame_left @ T_tip), t)

    def write_actuators(self, t: float, commanded: Array, measured: Array, arm: str | None = None) -> None:
        """Commanded and measured actuator positions (the reference arm: phi [rad], d, s1a, s1b,
        s2a, s2b [m]; any arm: its ``actuator_names``, rad or m each) at host monotonic time ``t``
        [s] (e.g. the capture time of the frame the command used), of arm ``arm``."""
        t_ns = self.stamp_ns(t)
        names = self.arm_actuators[arm]
        for frame_id, values in (("commanded", commanded), ("measured", measured)):
            q = np.asarray(values, float).reshape(-1)
            if q.size != len(names):
                raise InputError(f"expected {len(names)} actuator positions, got {q.size}")
            msg = self._store.types[JOINT_TYPE](
                header=header_msg(self._store, t_ns, frame_id), name=list(names), position=q,
                velocity=np.zeros(0), effort=np.zeros(0),
            )
            self._write(arm_topics(arm)[2], msg, t_ns)

    def close(self) -> None:
        """Finish the bag and move it to ``path`` (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._writer.close()
        inner = self._partial / f"{self._partial.name}.mcap"
        inner.replace(self.path)
        shutil.rmtree(self._partial, ignore_errors=True)

    def __enter__(self) -> BagRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
