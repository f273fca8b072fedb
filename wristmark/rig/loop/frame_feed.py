"""How the servo loop takes frames from a stereo source without ever blocking on the camera.

:class:`SynchronousFeed` reads the source in the loop's own thread: for sources that produce a
frame on demand (the simulated bench's renderer in simulated time, a file). :class:`LatestFrameFeed`
reads a live source (camera, network stream) in a thread of its own and keeps only the newest
frame: each control cycle takes the newest frame not handed out yet, waiting a bounded time for
one captured after the cycle began, so a stalled camera costs the loop a lost cycle (the arm
held), never a blocked loop that would starve the actuator box's watchdog.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Protocol

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame, StereoSource


class FrameFeed(Protocol):
    """The loop's view of a frame source. ``last_arrival``: when the frame take() returned last
    became available to the loop (``time.monotonic()`` [s]; NaN for on-demand sources), so that
    ``last_arrival - frame.t_capture`` is the frame's own transport (exposure or rendering,
    encoding, network, decoding) when the source carries the capture time."""

    name: str
    last_arrival: float

    def take(self, fresh_after: float = -math.inf, wait_until: float = -math.inf) -> StereoFrame | None:
        """The newest frame not handed out yet, or None when there is none (a lost cycle).
        Raises FrameSourceError when the source failed or ended."""
        ...

    @property
    def dropped(self) -> int:
        """Frames captured but never handed out to the loop."""
        ...

    def close(self) -> None:
        """Stop reading and close the source."""
        ...


class SynchronousFeed:
    """Every take() reads the source once (on-demand sources: a renderer, a file)."""

    def __init__(self, source: StereoSource) -> None:
        self.source = source
        self.name = source.name
        self.last_arrival = math.nan

    def take(self, fresh_after: float = -math.inf, wait_until: float = -math.inf) -> StereoFrame | None:
        """The source's next frame; FrameSourceError when it has ended."""
        frame = self.source.read()
        if frame is None:
            raise FrameSourceError(f"{self.name}: the source ended")
        return frame

    @property
    def dropped(self) -> int:
        """The source's own count."""
        return int(self.source.dropped)

    def close(self) -> None:
        """Close the source."""
        self.source.close()


class LatestFrameFeed:
    """A reader thread keeps the newest frame of a live source.

    take(fresh_after, wait_until): the newest frame not handed out yet; while that frame arrived
    before ``fresh_after`` (or there is none), wait for a newer one until ``wait_until`` (both on
    ``time.monotonic()`` [s]); at the deadline hand out the newest unseen frame, however old, or
    None. A frame's arrival is when this feed's reader got it from the source. The source's
    error (a stall it detected, the stream ending) is raised by the
    next take(). Frames replaced before anyone took them count in :attr:`dropped`.
    """

    def __init__(self, source: StereoSource) -> None:
        self.source = source
        self.name = source.name
        self._cond = threading.Condition()
        self._latest: StereoFrame | None = None
        self._latest_arrival = math.nan
        self.last_arrival = math.nan
        self._taken_index: int | None = None
        self._error: FrameSourceError | None = None
        self._replaced = 0
        self.received = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_forever, name=f"frames:{self.name}", daemon=True)
        self._thread.start()

    def _read_forever(self) -> None:
        while not self._stop.is_set():
            try:
                frame = self.source.read()
            except FrameSourceError as e:
                err: FrameSourceError | None = e
                frame = None
            except Exception as e:  # noqa: BLE001 - any reader failure becomes one line for the loop
                err = FrameSourceError(f"{self.name}: {type(e).__name__}: {e}")
                frame = None
            else:
                err = None if frame is not None else FrameSourceError(f"{self.name}: the stream ended")
            with self._cond:
                if err is not None:
                    if not self._stop.is_set():
                        self._error = err
                    self._cond.notify_all()
                    return
                assert frame is not None
                if self._latest is not None and self._latest.index != self._taken_index:
                    self._replaced += 1
                self._latest = frame
                self._latest_arrival = time.monotonic()
                self.received += 1
                self._cond.notify_all()

    def _unseen(self) -> StereoFrame | None:
        f = self._latest
        return f if f is not None and f.index != self._taken_index else None

    def take(self, fresh_after: float = -math.inf, wait_until: float = -math.inf) -> StereoFrame | None:
        """See the class docstring."""
        with self._cond:
            while True:
                f = self._unseen()
                if f is not None and self._latest_arrival >= fresh_after:
                    break
                if self._error is not None:
                    raise self._error
                remaining = wait_until - time.monotonic()
                if remaining <= 0:
                    break
                self._cond.wait(remaining)
            if f is not None:
                self._taken_index = f.index
                self.last_arrival = self._latest_arrival
            return f

    @property
    def dropped(self) -> int:
        """Frames the source dropped plus frames replaced here before the loop took them."""
        return int(self.source.dropped) + self._replaced

    def close(self) -> None:
        """Stop the reader (it ends at its next frame or the source's timeout) and close the source."""
        self._stop.set()
        try:
            self.source.close()
        finally:
            self._thread.join(2.0)
