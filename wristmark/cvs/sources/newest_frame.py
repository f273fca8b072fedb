"""A one-frame mailbox between a capturing thread and a consumer: the newest frame wins.

The producer :meth:`NewestFrame.put` s every captured frame; a frame that was never taken
before the next one arrived counts as dropped. The consumer :meth:`NewestFrame.take` s the
newest frame it has not seen, waiting up to a timeout. The producer ends the stream with
:meth:`finish` (an error message for a live source that must not end, None for the end of a
file).
"""

from __future__ import annotations

import threading
import time

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame


class NewestFrame:
    """Thread-safe newest-frame slot with a dropped-frame counter."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._frame: StereoFrame | None = None
        self._fresh = False  # the slot holds a frame not yet taken
        self._finished = False
        self._error: str | None = None
        self.captured = 0  # frames put [-]
        self.dropped = 0  # frames replaced before anyone took them [-]

    def put(self, frame: StereoFrame) -> None:
        """Offer a new frame (replaces an untaken one, which counts as dropped)."""
        with self._cond:
            if self._fresh:
                self.dropped += 1
            self._frame, self._fresh = frame, True
            self.captured += 1
            self._cond.notify_all()

    def skip(self) -> None:
        """Count a frame the producer discarded itself (e.g. it was too late to decode)."""
        with self._cond:
            self.captured += 1
            self.dropped += 1

    def finish(self, error: str | None = None) -> None:
        """No more frames: ``error`` (one line) is raised by the next take once the slot is
        empty, or None for a normal end. The first call decides; later ones are ignored."""
        with self._cond:
            if self._finished:
                return
            self._finished, self._error = True, error
            self._cond.notify_all()

    def take(self, timeout: float, stall_message: str) -> StereoFrame | None:
        """The newest untaken frame; None after a normal end; FrameSourceError(stall_message)
        when nothing new arrived for ``timeout`` [s], or the producer's error."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not self._fresh:
                if self._finished:
                    if self._error:
                        raise FrameSourceError(self._error)
                    return None
                left = deadline - time.monotonic()
                if left <= 0:
                    raise FrameSourceError(stall_message)
                self._cond.wait(left)
            self._fresh = False
            return self._frame
