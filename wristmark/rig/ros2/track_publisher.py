"""``wristmark track --ros2 [NS]``: each tracked pair's tip on ``NS/measured_cp`` and the marker's
pose on ``NS/marker/measured_cp`` (geometry_msgs/PoseStamped), over Cyclone DDS without ROS.

Frames: with the calibration's ``world_T_left`` (or ``--registration``) both are in {w}, frame_id
``world`` (as ``servo --ros2``); without, in the left camera's frame {ll}, frame_id
``left_camera``. Positions [m]: the tip, and the origin of {wm}; the orientation of both is {wm}'s
(the tip frame's; with the reference sleeve its roll about z is known only modulo a column).
Stamp: the frame's capture time (``t_capture``, host monotonic clock) on the host's system clock
(ROS time), as the servo bridge stamps a frame. A pair whose marker is not found publishes
nothing.

The tracking thread never waits for DDS: :meth:`TrackPublisher.on_pair` appends the pair to a
bounded queue (the oldest is dropped and counted when the publisher thread falls ``QUEUE`` pairs
behind) and a publisher thread converts, serializes and writes. QoS as the servo bridge's outputs:
reliable, keep last 10, volatile. Loopback only unless ``CYCLONEDDS_URI`` says otherwise
(rig/ros2/dds_config.py).
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.rig.ros2.bridge import WORLD_FRAME, clean_namespace, duration_ms
from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds

Array = NDArray[np.float64]
LEFT_CAMERA_FRAME = "left_camera"  # frame_id of {ll}, the left camera's frame (no world_T_left)
QUEUE = 256  # pairs the publisher thread may fall behind before the oldest is dropped


class TrackPublisher:
    """Publishes tracked pairs' tip and marker pose; ``T_world_left`` (4x4, None: no {w}) picks the frame."""

    def __init__(self, namespace: str | None, T_world_left: Array | None = None) -> None:
        require_cyclonedds()
        from cyclonedds.core import Policy, Qos
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2 import messages as M

        self.M = M
        self.namespace = clean_namespace(namespace)
        self.W = None if T_world_left is None else np.asarray(T_world_left, float).reshape(4, 4)
        self.frame_id = WORLD_FRAME if self.W is not None else LEFT_CAMERA_FRAME
        self.published = 0  # pairs written (both topics)
        self.not_found = 0  # pairs without a pose: nothing published
        self.dropped = 0  # pairs dropped because the publisher thread was QUEUE pairs behind
        self.publish_errors = 0
        self.hook_s: list[float] = []  # the tracking thread's time in :meth:`on_pair` per pair [s]
        self._epoch_minus_mono = time.time() - time.monotonic()
        self.participant = open_participant()
        qos = Qos(Policy.Reliability.Reliable(duration_ms(100)), Policy.History.KeepLast(10),
                  Policy.Durability.Volatile)

        def writer(name: str) -> Any:
            return DataWriter(self.participant, Topic(self.participant, M.topic_name(self.topic(name)),
                                                      M.PoseStamped), qos)

        self._tip = writer("measured_cp")
        self._marker = writer("marker/measured_cp")
        self._queue: collections.deque[tuple[float, Array, Array]] = collections.deque()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = False
        self._thread = threading.Thread(target=self._publish_forever, daemon=True, name="wristmark-track-ros2")
        self._thread.start()

    def topic(self, name: str) -> str:
        """The ROS 2 topic ``NS/name``."""
        return f"{self.namespace}/{name}"

    def on_pair(self, t_capture: float, res: Any) -> None:
        """Hand one tracked pair (a cvs.tracking.tracker.TrackResult; ``t_capture`` [s], host
        monotonic clock) to the publisher thread; never blocks. No pose: nothing published."""
        c0 = time.perf_counter()
        if not (res.ok and res.T_left_marker is not None and res.tip_left is not None):
            self.not_found += 1
        else:
            item = (self._epoch_minus_mono + float(t_capture), res.T_left_marker, res.tip_left)
            with self._lock:
                if len(self._queue) >= QUEUE:
                    self._queue.popleft()
                    self.dropped += 1
                self._queue.append(item)
            self._wake.set()
        self.hook_s.append(time.perf_counter() - c0)

    def _publish_forever(self) -> None:
        while True:
            self._wake.wait()
            with self._lock:
                self._wake.clear()
                items = list(self._queue)
                self._queue.clear()
                stop = self._stop
            for item in items:
                try:
                    self._publish(*item)
                    self.published += 1
                except Exception:  # noqa: BLE001 - a DDS failure must not stop tracking; counted
                    self.publish_errors += 1
            if stop:
                return

    def poses(self, T_left_marker: Array, tip_left: Array) -> tuple[Array, Array]:
        """The marker's pose (4x4) and the tip [m] in the published frame ({w} or {ll})."""
        T = np.asarray(T_left_marker, float).reshape(4, 4)
        tip = np.asarray(tip_left, float).reshape(3)
        if self.W is None:
            return T, tip
        return self.W @ T, self.W[:3, :3] @ tip + self.W[:3, 3]

    def _publish(self, stamp: float, T_left_marker: Array, tip_left: Array) -> None:
        M = self.M
        T, tip = self.poses(T_left_marker, tip_left)
        header = M.Header(M.Time.of_seconds(stamp), self.frame_id)
        q = M.Quaternion(*map(float, Rotation.from_matrix(T[:3, :3]).as_quat()))
        self._tip.write(M.PoseStamped(header, M.Pose(M.Point(*map(float, tip)), q)))
        self._marker.write(M.PoseStamped(header, M.Pose(M.Point(*map(float, T[:3, 3])), q)))

    def report(self) -> dict[str, Any]:
        """Topics and counters; the tracking thread's time in the hook [ms]."""
        hook = np.asarray(self.hook_s, float) * 1000.0
        return {"namespace": self.namespace, "frame_id": self.frame_id,
                "published": [self.topic("measured_cp"), self.topic("marker/measured_cp")],
                "pairs_published": self.published, "pairs_without_pose": self.not_found,
                "pairs_dropped": self.dropped, "publish_errors": self.publish_errors,
                "hook_ms": {"median": float(np.median(hook)) if hook.size else None,
                            "max": float(hook.max()) if hook.size else None}}

    def line(self) -> str:
        """One summary line for stderr."""
        r = self.report()
        med = r["hook_ms"]["median"]
        return (f"track --ros2: {r['pairs_published']} pairs published on {' and '.join(r['published'])} "
                f"(frame_id {self.frame_id}), {r['pairs_without_pose']} without a pose, {r['pairs_dropped']} "
                f"dropped, {r['publish_errors']} errors; hook median "
                f"{'-' if med is None else f'{med:.3f}'} ms")

    def close(self, ack_timeout_s: float = 1.0) -> None:
        """Publish what is queued, wait up to ``ack_timeout_s`` for reliable readers' acks, stop."""
        with self._lock:
            self._stop = True
        self._wake.set()
        self._thread.join(timeout=5.0)
        for w in (self._tip, self._marker):
            try:
                w.wait_for_acks(duration_ms(1000.0 * ack_timeout_s))
            except Exception:  # noqa: BLE001 - a reader that never acks must not hang the end
                pass
        self.participant = None  # cyclonedds deletes the entities with the last reference

    def __enter__(self) -> TrackPublisher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
