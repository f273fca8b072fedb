"""The servo loop on a ROS 2 graph (``wristmark servo --ros2 [NS]``), over Cyclone DDS without
ROS: out, ``NS/measured_cp`` (geometry_msgs/PoseStamped: the tracked tip in {w}, frame_id
``world``, position [m] and the tip frame's orientation when it is measured),
``NS/marker/measured_cp`` (PoseStamped: the measured marker's pose {wm} in {w}, frame_id ``world``,
the origin of {wm} [m] and its orientation; published with the tip, when measured), ``NS/measured_js``
and ``NS/setpoint_js`` (sensor_msgs/JointState: the actuators measured by the encoders and
commanded, names phi, d, s1a, s1b, s2a, s2b [rad, m]); in (``--target ros2``), ``NS/servo_cp``
(geometry_msgs/PoseStamped in frame ``world``: the tip's target), fed into the live target store
(rig/targets/live_target.py: clamped, speed bounded, held when silent; a wrong frame_id, a
non-finite number or a zero quaternion is counted and dropped with a warning).

The loop never waits for DDS: its hook copies the cycle into a one-slot mailbox (the newest
wins) and a publisher thread serializes and writes. QoS: the outputs reliable, keep last 10,
volatile (ROS 2's default: ``ros2 topic echo``, RViz and Foxglove subscribe as they like);
``servo_cp`` read best effort, keep last 1 (matches reliable and best-effort publishers; only
the newest target matters). Stamps: the host's system clock (ROS time), at the frame's capture
when it is known on the wall clock. Loopback only unless ``CYCLONEDDS_URI`` says otherwise
(rig/ros2/dds_config.py).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_spec import Arm, actuator_names
from wristmark.models.errors import InputError
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds
from wristmark.rig.targets.live_target import LiveTargets, rotation_of_quaternion

Array = NDArray[np.float64]
WORLD_FRAME = "world"  # frame_id of {w} (the robot base), as in the bags (rig/recording/bag_recorder.py)
DEFAULT_NAMESPACE = "wristmark"


def clean_namespace(ns: str | None) -> str:
    """``/arm/`` -> ``/arm``; empty or None: ``/wristmark``; ValueError for a name ROS 2 refuses."""
    name = (ns or DEFAULT_NAMESPACE).strip().strip("/")
    parts = name.split("/")
    if not all(p and (p[0].isalpha() or p[0] == "_") and all(c.isalnum() or c == "_" for c in p) for p in parts):
        raise ValueError(f"ROS 2 namespace {ns!r}: use letters, digits and _ between slashes, not starting "
                         "with a digit")
    return "/" + name


def check_namespace_option(namespace: str, what: str = "--ros2") -> None:
    """An option's ROS 2 namespace: valid, and cyclonedds installed (InputError naming ``what``, one line)."""
    try:
        clean_namespace(namespace)
    except ValueError as e:
        raise InputError(f"{what}: {e}") from None
    require_cyclonedds(what)


@dataclass
class CycleSnapshot:
    """What one cycle publishes: stamp [s, system clock], tip [m] and rotation (or None), the
    commanded configuration psi [rad, m], the measured actuators [rad, m] (None: not known) and
    the marker's pose in {w} (4x4 [m]; None: not measured)."""

    stamp: float
    p: Array | None
    R: Array | None
    psi_cmd: Array
    measured: Array | None
    T_marker: Array | None = None


class Ros2Bridge:
    """Publishes the loop's cycles and (with ``targets``) feeds ``servo_cp`` into them."""

    def __init__(self, namespace: str | None, params: Arm, targets: LiveTargets | None = None,
                 frame_id: str = WORLD_FRAME, wall_clock: bool = False, participant: Any = None,
                 base: Array | None = None) -> None:
        """``participant``: a Cyclone DDS participant to share (None: its own, loopback unless
        ``CYCLONEDDS_URI`` says otherwise); ``base``: the arm's {w} in the frame ``frame_id`` names
        (4x4 [m]; None: the same frame), what goes out is moved into it and ``servo_cp`` out of it."""
        require_cyclonedds()
        from cyclonedds.core import Listener, Policy, Qos
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2 import messages as M

        self.M = M
        self.params = params
        self.namespace = clean_namespace(namespace)
        self.frame_id = frame_id
        self.wall_clock = wall_clock
        self.targets = targets
        self.published = 0
        self.skipped = 0  # cycles whose snapshot a newer one replaced before it was written
        self.publish_errors = 0
        self.hook_s: list[float] = []  # the loop thread's time in :meth:`on_cycle` per cycle [s]
        self._epoch_minus_mono = time.time() - time.monotonic()
        self.participant = open_participant() if participant is None else participant
        self.base = np.eye(4) if base is None else np.asarray(base, float)
        out_qos = Qos(Policy.Reliability.Reliable(duration_ms(100)), Policy.History.KeepLast(10),
                      Policy.Durability.Volatile)

        def writer(name: str, cls: type) -> Any:
            return DataWriter(self.participant, Topic(self.participant, M.topic_name(self.topic(name)), cls), out_qos)

        self._cp = writer("measured_cp", M.PoseStamped)
        self._marker = writer("marker/measured_cp", M.PoseStamped)
        self._js = writer("measured_js", M.JointState)
        self._sp = writer("setpoint_js", M.JointState)
        self._reader = None
        if targets is not None:
            in_qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1), Policy.Durability.Volatile)
            topic = Topic(self.participant, M.topic_name(self.topic("servo_cp")), M.PoseStamped)
            self._reader = DataReader(self.participant, topic, in_qos,
                                      listener=Listener(on_data_available=self._on_servo_cp))
        self._slot: CycleSnapshot | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = False
        self._thread = threading.Thread(target=self._publish_forever, daemon=True, name="wristmark-ros2-publish")
        self._thread.start()

    def topic(self, name: str) -> str:
        """The ROS 2 topic ``NS/name``."""
        return f"{self.namespace}/{name}"

    # -- out ---------------------------------------------------------------------------------
    def on_cycle(self, rec: CycleRecord, link: Any) -> None:
        """The loop's hook: hand the cycle to the publisher thread (never blocks; the newest wins).
        The commanded actuators come from the record's configuration; the measured ones are the
        link's last state (serial links: no extra request) or, in process, the simulated encoders."""
        c0 = time.perf_counter()
        state = getattr(link, "state", None)
        if state is not None:
            measured: Array | None = np.asarray(state.positions, float)
        elif getattr(link, "driver", None) is None and hasattr(link, "arm"):
            measured = np.asarray(link.measured_actuators(), float)  # in process (direct link)
        else:
            measured = None
        t = rec.t_capture if self.wall_clock and math.isfinite(rec.t_capture) else rec.t_wall
        snap = CycleSnapshot(self._epoch_minus_mono + t, None if rec.p_est is None else np.array(rec.p_est, float),
                             None if rec.R_est is None else np.array(rec.R_est, float),
                             np.array(rec.psi_cmd, float), measured,
                             None if rec.T_marker_est is None else np.array(rec.T_marker_est, float))
        with self._lock:
            self.skipped += int(self._slot is not None)
            self._slot = snap
        self._wake.set()
        self.hook_s.append(time.perf_counter() - c0)

    def _publish_forever(self) -> None:
        while True:
            self._wake.wait()
            with self._lock:
                self._wake.clear()
                snap, self._slot = self._slot, None
                stop = self._stop
            if snap is not None:
                try:
                    self._publish(snap)
                    self.published += 1
                except Exception:  # noqa: BLE001 - a DDS failure must not stop the loop; counted
                    self.publish_errors += 1
            if stop:
                return

    def _publish(self, s: CycleSnapshot) -> None:
        M = self.M
        header = M.Header(M.Time.of_seconds(s.stamp), self.frame_id)
        B = self.base
        if s.p is not None:
            q = Rotation.from_matrix(B[:3, :3] @ s.R).as_quat() if s.R is not None else np.array([0.0, 0.0, 0.0, 1.0])
            p = B[:3, :3] @ s.p + B[:3, 3]
            self._cp.write(M.PoseStamped(header, M.Pose(M.Point(*map(float, p)), M.Quaternion(*map(float, q)))))
            if s.T_marker is not None:
                T = B @ s.T_marker
                qm = Rotation.from_matrix(T[:3, :3]).as_quat()
                self._marker.write(M.PoseStamped(header, M.Pose(M.Point(*map(float, T[:3, 3])),
                                                                M.Quaternion(*map(float, qm)))))
        names = list(actuator_names(self.params))
        setpoint = actuators_from_psi(self.params, s.psi_cmd)
        self._sp.write(M.JointState(header, names, [float(x) for x in setpoint], [], []))
        if s.measured is not None:
            self._js.write(M.JointState(header, names, [float(x) for x in s.measured], [], []))

    # -- in ----------------------------------------------------------------------------------
    def _on_servo_cp(self, reader: Any) -> None:
        """servo_cp arrived (Cyclone's listener thread): validate, offer to the target store."""
        assert self.targets is not None
        try:
            samples = reader.take(N=16)
        except Exception as e:  # noqa: BLE001 - an undecodable sample is dropped, counted
            self.targets.drop(f"undecodable servo_cp ({type(e).__name__})")
            return
        for msg in samples:
            if hasattr(msg, "pose"):  # not an InvalidSample (a writer leaving: no data)
                self.offer(msg)

    def offer(self, msg: Any) -> bool:
        """One servo_cp message into the target store (False: dropped, counted, warned)."""
        assert self.targets is not None
        frame = getattr(getattr(msg, "header", None), "frame_id", None)
        if frame != self.frame_id:
            self.targets.drop(f"servo_cp frame_id {frame!r}, need {self.frame_id!r}")
            return False
        pos, ori = msg.pose.position, msg.pose.orientation
        p = np.array([pos.x, pos.y, pos.z], float)
        if not np.all(np.isfinite(p)):
            self.targets.drop("servo_cp position not finite")
            return False
        try:
            R = rotation_of_quaternion(np.array([ori.x, ori.y, ori.z, ori.w], float))
        except ValueError as e:
            self.targets.drop(f"servo_cp {e}")
            return False
        Rb = self.base[:3, :3]  # into the arm's own {w}
        p, R = Rb.T @ (p - self.base[:3, 3]), Rb.T @ R
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        return self.targets.offer(p, R, stamp if stamp > 0 else float("nan"))

    # -- end ---------------------------------------------------------------------------------
    def report(self) -> dict[str, Any]:
        """Topics and counters for the result JSON; the loop's time in the hook [ms]."""
        hook = np.asarray(self.hook_s, float) * 1000.0
        topics = [self.topic(n) for n in ("measured_cp", "marker/measured_cp", "measured_js", "setpoint_js")]
        return {"namespace": self.namespace, "frame_id": self.frame_id, "published": topics,
                "subscribed": [self.topic("servo_cp")] if self._reader is not None else [],
                "cycles_published": self.published, "cycles_replaced": self.skipped,
                "publish_errors": self.publish_errors,
                "hook_ms": {"median": float(np.median(hook)) if hook.size else None,
                            "max": float(hook.max()) if hook.size else None}}

    def close(self) -> None:
        """Publish what is left, stop the thread, delete the participant's entities."""
        with self._lock:
            self._stop = True
        self._wake.set()
        self._thread.join(timeout=2.0)
        if self._reader is not None:
            self._reader.set_listener(None)
        self.participant = None  # cyclonedds deletes the entities with the last reference

    def __enter__(self) -> Ros2Bridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def duration_ms(ms: float) -> int:
    """A Cyclone DDS duration [ns] of ``ms`` milliseconds."""
    return int(ms * 1_000_000)
