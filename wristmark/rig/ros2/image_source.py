"""A stereo camera on a ROS 2 graph as a frame source: ``ros2:LEFT,RIGHT`` (``wristmark track
--source``, ``wristmark servo --serial PORT --camera``), two image topics read over Cyclone DDS
without ROS (loopback only unless ``CYCLONEDDS_URI`` says otherwise: rig/ros2/dds_config.py).

A topic whose name ends in ``/compressed`` carries sensor_msgs/CompressedImage (JPEG or PNG, the
image_transport convention), any other sensor_msgs/Image (bgr8, rgb8, mono8, bgra8, rgba8). A left
and a right image make a pair when their header stamps agree within ``tolerance`` [s] (default
2 ms: a synchronised stereo camera stamps both alike); unstamped images (stamp 0) pair by arrival
within the same tolerance plus 20 ms. Live-source semantics (cvs/sources/frames.py): ``read()``
hands out the newest pair not yet handed out, waiting up to ``timeout`` [s] (then a one-line
FrameSourceError: the cameras stalled); pairs replaced before they were read, and images that
found no partner, count in ``dropped``. Images are decoded in ``read()`` (the consumer's thread),
never in DDS's receive thread.

``t_capture`` is the header stamp (the publisher's system clock) moved onto this host's
``time.monotonic()``, assuming synchronised clocks (same host, NTP or PTP); a stamp more than 1 s
from the arrival (unsynchronised clocks), or none, gives the arrival time instead.
QoS: best effort, keep last 2 (matches a camera driver's sensor-data profile and a reliable one).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame, StereoSource
from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds

PREFIX = "ros2:"
PAIR_TOLERANCE_S = 0.002
UNSTAMPED_EXTRA_S = 0.020
CLOCK_TRUST_S = 1.0  # [s] a stamp further than this from the arrival is not on our clock
KEEP = 8  # images kept per side while waiting for a partner


def is_ros2_spec(spec: object) -> bool:
    """True for ``ros2:LEFT,RIGHT``."""
    return isinstance(spec, str) and spec.startswith(PREFIX)


def parse_ros2_spec(spec: str) -> tuple[str, str]:
    """``ros2:/a/left/image_raw,/a/right/image_raw`` -> the two topic names (FrameSourceError, one
    line, for anything else)."""
    parts = [p.strip() for p in spec[len(PREFIX):].split(",")]
    if len(parts) != 2 or not all(p.startswith("/") and len(p) > 1 and " " not in p for p in parts):
        raise FrameSourceError(f"{spec}: a ROS 2 camera is ros2:LEFT,RIGHT, two image topics starting with '/' "
                               "(e.g. ros2:/stereo/left/image_raw,/stereo/right/image_raw)")
    if parts[0] == parts[1]:
        raise FrameSourceError(f"{spec}: the left and right topics must differ")
    return parts[0], parts[1]


@dataclass(frozen=True)
class Received:
    """One image message as it arrived: stamp [ns] (0: none), arrival [s, monotonic], the message."""

    stamp_ns: int
    arrival: float
    msg: Any


class StereoPairer:
    """Pairs left and right images by stamp (thread-safe); the newest complete pair wins."""

    def __init__(self, tolerance: float = PAIR_TOLERANCE_S) -> None:
        self.tolerance = float(tolerance)
        self._cond = threading.Condition()
        self._left: deque[Received] = deque(maxlen=KEEP)
        self._right: deque[Received] = deque(maxlen=KEEP)
        self._pair: tuple[Received, Received] | None = None
        self._last_paired_ns = -1
        self.pairs = 0
        self.replaced = 0  # complete pairs replaced by a newer one before they were taken
        self.unpaired = 0  # images that found no partner (pushed out of the queue, or older than a pair)

    def add(self, side: str, item: Received) -> None:
        """A left or right image arrived: pair it with the other side's closest one if it can."""
        with self._cond:
            mine, other = (self._left, self._right) if side == "left" else (self._right, self._left)
            if len(mine) == mine.maxlen:
                self.unpaired += 1
            mine.append(item)
            match = self._partner(item, other)
            if match is None:
                return
            left, right = (item, match) if side == "left" else (match, item)
            t_pair = max(left.stamp_ns, right.stamp_ns) if left.stamp_ns and right.stamp_ns else -1
            if t_pair != -1 and t_pair <= self._last_paired_ns:
                return  # older than a pair already made
            # the pair's images and everything older leave the queues; older ones never found a partner
            for q, used in ((self._left, left), (self._right, right)):
                while q:
                    x = q.popleft()
                    if x is used:
                        break
                    self.unpaired += 1
            self._last_paired_ns = max(t_pair, self._last_paired_ns)
            self.replaced += int(self._pair is not None)
            self._pair = (left, right)
            self.pairs += 1
            self._cond.notify_all()

    def _partner(self, item: Received, other: deque[Received]) -> Received | None:
        best, best_d = None, float("inf")
        for x in other:
            if item.stamp_ns and x.stamp_ns:
                d = abs(item.stamp_ns - x.stamp_ns) * 1e-9
                ok = d <= self.tolerance
            else:
                d = abs(item.arrival - x.arrival)
                ok = d <= self.tolerance + UNSTAMPED_EXTRA_S
            if ok and d < best_d:
                best, best_d = x, d
        return best

    def take(self, timeout: float) -> tuple[Received, Received] | None:
        """The newest pair not yet taken, waiting up to ``timeout`` [s] (None: none came)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._pair is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._cond.wait(remaining)
            pair, self._pair = self._pair, None
            return pair

    def wake(self) -> None:
        """Wake a waiting :meth:`take` (closing)."""
        with self._cond:
            self._cond.notify_all()


def decode(msg: Any, compressed: bool, where: str) -> np.ndarray:
    """The 8-bit image (BGR or grey) of an Image / CompressedImage message of ours."""
    from wristmark.cvs.sources.ros_image_msgs import COMPRESSED, IMAGE, image_from_msg

    data = np.frombuffer(bytes(msg.data), np.uint8)
    if compressed:
        view = SimpleNamespace(format=msg.format, data=data)
        return image_from_msg(view, COMPRESSED, where)
    view = SimpleNamespace(encoding=msg.encoding, height=msg.height, width=msg.width, step=msg.step, data=data)
    return image_from_msg(view, IMAGE, where)


class Ros2StereoSource:
    """``ros2:LEFT,RIGHT``: a live stereo source from two ROS 2 image topics (module docstring)."""

    def __init__(self, spec: str, timeout: float = 5.0, tolerance: float = PAIR_TOLERANCE_S,
                 participant: Any = None) -> None:
        """participant: one of dds_config.open_participant shared with the process's other ROS 2
        parts (None: its own)."""
        require_cyclonedds(f"--source {spec}")
        self.topics = parse_ros2_spec(spec)
        self.name = spec
        self.timeout = float(timeout)
        self.pairer = StereoPairer(tolerance)
        self._index = 0
        self._closed = False
        self._epoch_minus_mono = time.time() - time.monotonic()
        from cyclonedds.core import Listener, Policy, Qos
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2.messages import CompressedImage, Image, topic_name

        self.compressed = tuple(t.rstrip("/").endswith("/compressed") for t in self.topics)
        self.participant = participant if participant is not None else open_participant()
        qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(2), Policy.Durability.Volatile)
        self._readers = []
        for side, topic, comp in zip(("left", "right"), self.topics, self.compressed):
            cls = CompressedImage if comp else Image
            listener = Listener(on_data_available=lambda r, side=side: self._on_images(side, r))
            self._readers.append(DataReader(self.participant, Topic(self.participant, topic_name(topic), cls), qos,
                                            listener=listener))

    def _on_images(self, side: str, reader: Any) -> None:
        now = time.monotonic()
        try:
            samples = reader.take(N=4)
        except Exception:  # noqa: BLE001 - an undecodable sample is an image without a partner
            self.pairer.unpaired += 1
            return
        for msg in samples:
            if not hasattr(msg, "data"):
                continue  # an InvalidSample: the writer left (no data)
            stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            self.pairer.add(side, Received(max(stamp, 0), now, msg))

    def _t_capture(self, left: Received, right: Received) -> float:
        arrival = max(left.arrival, right.arrival)
        if not (left.stamp_ns and right.stamp_ns):
            return arrival
        t = 0.5e-9 * (left.stamp_ns + right.stamp_ns) - self._epoch_minus_mono
        return t if abs(arrival - t) <= CLOCK_TRUST_S else arrival

    def read(self) -> StereoFrame | None:
        """The newest pair not yet handed out (decoded); FrameSourceError when none came within
        the timeout; None once closed."""
        pair = self.pairer.take(self.timeout)
        if self._closed:
            return None
        if pair is None:
            raise FrameSourceError(f"{self.name}: no stereo pair for {self.timeout:g} s (are both topics "
                                   "published, stamped alike, and on this DDS domain and network?)")
        left, right = pair
        imgs = [decode(x.msg, comp, f"{self.name} ({topic})")
                for x, comp, topic in zip(pair, self.compressed, self.topics)]
        frame = StereoFrame(imgs[0], imgs[1], self._t_capture(left, right), self._index,
                            self.topics[0], self.topics[1])
        self._index += 1
        return frame

    @property
    def dropped(self) -> int:
        """Pairs replaced before they were read, and images that found no partner."""
        return self.pairer.replaced + self.pairer.unpaired

    def close(self) -> None:
        """Stop listening (idempotent)."""
        if self._closed:
            return
        self._closed = True
        for r in self._readers:
            r.set_listener(None)
        self.pairer.wake()
        self._readers = []
        self.participant = None


def open_frame_source(spec: Any, options: Any = None, participant: Any = None) -> StereoSource:
    """``cvs.sources.open_source.open_stereo_source`` that also opens ``ros2:LEFT,RIGHT`` (with its
    size check and grey conversion from ``options``; on ``participant`` when given, one of
    dds_config.open_participant, else its own)."""
    from wristmark.cvs.sources.open_source import CheckedSource, SourceOptions, open_stereo_source

    if not is_ros2_spec(spec):
        return open_stereo_source(spec, options)
    o = options or SourceOptions()
    o.validate()
    source: StereoSource = Ros2StereoSource(spec, timeout=o.timeout, participant=participant)
    if o.image_size is None and not o.grayscale:
        return source
    size = None if o.image_size is None else (int(o.image_size[0]), int(o.image_size[1]))
    return CheckedSource(source, size, o.grayscale)  # type: ignore[return-value]
