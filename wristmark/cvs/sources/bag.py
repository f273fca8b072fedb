"""Stereo frames from a ROS 2 bag (``FILE.mcap``, ``FILE.db3``, or a bag directory with
sqlite3 or MCAP storage) read with rosbags, no ROS install needed.

The left and right topics (default ``/stereo/left/image_raw``, ``/stereo/right/image_raw``)
carry ``sensor_msgs/msg/Image`` (bgr8, rgb8, mono8) or ``sensor_msgs/msg/CompressedImage``.
A first pass reads only the stamps (the header's, or the log time when the header's is zero):
a left and a right image are a pair when each is the other's nearest in stamp and they lie
less than half a frame period apart; unpaired left images count as ``dropped``. The second
pass hands out the pairs in stamp order.

Time: the bag's stamps are mapped to the host's monotonic clock from the first ``read()``:
``t_capture = t_first_read + (stamp - first_stamp)`` [s]. Unpaced (default) pairs are handed
out as fast as they are read (their ``t_capture`` then says when they would have been
captured); ``paced=True`` waits until each pair's ``t_capture``, replaying the bag at its
recorded rate.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame
from wristmark.cvs.sources.ros_image_msgs import IMAGE_TYPES, image_from_msg, typestore


def _header_stamp_ns(raw: bytes | memoryview, log_ns: int) -> int:
    """The std_msgs/Header stamp at the start of a little-endian CDR message [ns] (log time if
    zero or not little-endian)."""
    b = bytes(raw[:12])
    if len(b) < 12 or b[1] != 1:  # encapsulation 0x0001 = CDR little-endian
        return log_ns
    sec, nanosec = struct.unpack_from("<iI", b, 4)
    t = sec * 1_000_000_000 + nanosec
    return t if t > 0 else log_ns


def mutual_nearest_pairs(left_ns: Sequence[int], right_ns: Sequence[int]) -> list[tuple[int, int]]:
    """Index pairs (i, j), in left order, of stamps that are each other's nearest and closer
    than half the median left period (any gap when there is a single left stamp)."""
    L, R = np.asarray(left_ns, np.int64), np.asarray(right_ns, np.int64)
    if L.size == 0 or R.size == 0:
        return []
    order_l, order_r = np.argsort(L, kind="stable"), np.argsort(R, kind="stable")
    Ls, Rs = L[order_l], R[order_r]

    def nearest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = np.clip(np.searchsorted(b, a), 1, len(b) - 1) if len(b) > 1 else np.zeros(len(a), int)
        if len(b) == 1:
            return k
        return np.where(np.abs(b[k - 1] - a) <= np.abs(b[k] - a), k - 1, k)

    j_of_i, i_of_j = nearest(Ls, Rs), nearest(Rs, Ls)
    gap = 0.5 * float(np.median(np.diff(Ls))) if Ls.size > 1 else np.inf
    return [(int(order_l[i]), int(order_r[j])) for i, j in enumerate(j_of_i)
            if i_of_j[j] == i and abs(int(Ls[i]) - int(Rs[j])) < max(gap, 1)]


class BagSource:
    """A finite stereo source over two image topics of a ROS 2 bag (module docstring)."""

    def __init__(self, path: str | Path, topics: tuple[str, str], paced: bool = False) -> None:
        from rosbags.highlevel import AnyReader

        self.path, self.topics, self.paced = Path(path), tuple(topics), bool(paced)
        self.name = str(self.path)
        if not self.path.exists():
            raise FrameSourceError(f"{self.path}: no such bag")
        self._reader: Any = None
        try:
            self._reader = AnyReader([self.path], default_typestore=typestore())
            self._reader.open()
        except Exception as e:  # rosbags raises several types for unreadable bags
            raise FrameSourceError(f"{self.path}: cannot read the bag ({type(e).__name__}: {e})") from e
        self._conns = []
        for topic in self.topics:
            conns = [c for c in self._reader.connections if c.topic == topic]
            if not conns:
                images = sorted({c.topic for c in self._reader.connections if c.msgtype in IMAGE_TYPES})
                self.close()
                raise FrameSourceError(f"{self.path}: no topic {topic} (image topics: {', '.join(images) or 'none'})")
            if conns[0].msgtype not in IMAGE_TYPES:
                self.close()
                raise FrameSourceError(f"{self.path}: {topic} is {conns[0].msgtype}, not an image topic")
            self._conns.append(conns[0])
        stamps: tuple[list[int], list[int]] = ([], [])
        for conn, log_ns, raw in self._reader.messages(connections=self._conns):
            stamps[self._side(conn)].append(_header_stamp_ns(raw, log_ns))
        self._pairs = mutual_nearest_pairs(*stamps)
        self._stamps = stamps
        self._unpaired = len(stamps[0]) - len(self._pairs)
        self._delivered = 0
        self._frames: Iterator[StereoFrame] | None = None

    def _side(self, conn: Any) -> int:
        return 0 if conn.topic == self.topics[0] else 1

    def __len__(self) -> int:
        return len(self._pairs)

    @property
    def dropped(self) -> int:
        """Left images that found no right partner."""
        return self._unpaired

    def _generate(self) -> Iterator[StereoFrame]:
        t_open = time.monotonic()
        first = self._stamps[0][self._pairs[0][0]] if self._pairs else 0
        want = {(0, i): n for n, (i, _) in enumerate(self._pairs)} | {(1, j): n for n, (_, j) in enumerate(self._pairs)}
        held: dict[int, list[Any]] = {}
        counts, next_pair = [0, 0], 0
        for conn, _, raw in self._reader.messages(connections=self._conns):
            side = self._side(conn)
            n = want.get((side, counts[side]))
            counts[side] += 1
            if n is None:
                continue
            where = f"{self.path}:{conn.topic}"
            held.setdefault(n, [None, None])[side] = image_from_msg(self._reader.deserialize(raw, conn.msgtype),
                                                                      conn.msgtype, where)
            while next_pair in held and all(v is not None for v in held[next_pair]):
                left, right = held.pop(next_pair)
                stamp = self._stamps[0][self._pairs[next_pair][0]]
                t = t_open + 1e-9 * (stamp - first)
                if self.paced and (wait := t - time.monotonic()) > 0:
                    time.sleep(wait)
                name = f"{self.path}@{stamp}"
                yield StereoFrame(left, right, t, next_pair, f"{name}:{self.topics[0]}", f"{name}:{self.topics[1]}")
                next_pair += 1

    def read(self) -> StereoFrame | None:
        """The next stereo pair in stamp order; None after the last."""
        if self._frames is None:
            self._frames = self._generate()
        return next(self._frames, None)

    def close(self) -> None:
        """Close the bag (idempotent)."""
        if self._reader is not None:
            self._reader.close()
            self._reader = None

