"""A live stereo source over an opened ``cv2.VideoCapture`` (a V4L2/UVC device or a network
stream) delivering both views in one frame (``sbs`` or ``tb``).

A grabbing thread reads frames as fast as the device or stream delivers them and keeps only
the newest (:class:`cvs.sources.newest_frame.NewestFrame`): ``read()`` returns the newest frame not yet
handed out, and every frame replaced before it was read counts in ``dropped``. ``decode``, when
given, turns what the capture read (e.g. a JPEG packet) into the image and maybe its capture
time. ``t_capture`` is that time, else ``stamp(capture, t_arrival)`` when given (e.g. the V4L2
buffer's monotonic timestamp), else ``time.monotonic()`` when the frame arrived; a sender's or
device's time is used only when it lies within a second before the arrival. ``index`` counts every frame the thread got
(delivered and dropped alike). No new frame for ``timeout`` s, or the end of the stream, is a
FrameSourceError naming the source.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame
from wristmark.cvs.sources.layout import check_layout, split_stereo
from wristmark.cvs.sources.newest_frame import NewestFrame

Stamp = Callable[[cv2.VideoCapture, float], float]
Decode = Callable[[NDArray[np.uint8]], tuple[NDArray[np.uint8], float | None]]
STAMP_WINDOW_S = 1.0  # a sender's or device's capture time older than this (or in the future) is not trusted [s]


def plausible_stamp(t: float | None, t_arrival: float) -> bool:
    """True when a reported capture time ``t`` [s] can be the monotonic time of a frame that
    arrived at ``t_arrival`` [s]."""
    return t is not None and t_arrival - STAMP_WINDOW_S <= t <= t_arrival + 1e-3


class LiveCaptureSource:
    """Newest-frame stereo source over an opened capture (see the module docstring).

    capture: an opened cv2.VideoCapture (owned: released by close); name: the SPEC, used in
    messages; layout: 'sbs' | 'tb'; timeout: stall timeout [s]; stamp: (capture, t_arrival) ->
    t_capture on the monotonic clock [s] (default: the arrival time); decode: packet -> (image,
    capture time or None)."""

    def __init__(self, capture: cv2.VideoCapture, name: str, layout: str = "sbs", timeout: float = 5.0,
                 stamp: Stamp | None = None, decode: Decode | None = None) -> None:
        self.name, self.layout, self.timeout = name, check_layout(layout), float(timeout)
        self._cap, self._stamp, self._decode = capture, stamp, decode
        self._slot = NewestFrame()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._grab, daemon=True, name=f"grab {name}")
        self._thread.start()

    @property
    def dropped(self) -> int:
        """Frames captured but replaced by a newer one before ``read()`` took them."""
        return self._slot.dropped

    @property
    def captured(self) -> int:
        """Frames the grabbing thread received."""
        return self._slot.captured

    def _grab(self) -> None:
        index = 0
        try:
            while not self._stop.is_set():
                ok, image = self._cap.read()
                t_arrival = time.monotonic()
                if self._stop.is_set():
                    break
                if not ok or image is None:
                    self._slot.finish(f"{self.name}: the stream ended (no more frames after {index})")
                    return
                t: float | None = None
                if self._decode is not None:
                    image, t = self._decode(np.asarray(image))
                if not plausible_stamp(t, t_arrival):
                    t = self._stamp(self._cap, t_arrival) if self._stamp is not None else None
                    t = t if plausible_stamp(t, t_arrival) else t_arrival
                assert t is not None
                left, right = split_stereo(np.asarray(image), self.layout, self.name)
                self._slot.put(StereoFrame(left, right, t, index, f"{self.name}#{index}", f"{self.name}#{index}"))
                index += 1
        except FrameSourceError as e:
            self._slot.finish(str(e))
        except cv2.error as e:
            self._slot.finish(f"{self.name}: capture failed ({str(e).strip().splitlines()[-1]})")
        self._slot.finish()

    def read(self) -> StereoFrame | None:
        """The newest frame not yet handed out (waits up to ``timeout`` s for one)."""
        if self._stop.is_set():
            raise FrameSourceError(f"{self.name}: the source is closed")
        frame = self._slot.take(self.timeout, f"{self.name}: no new frame for {self.timeout:g} s (stream stalled)")
        if frame is None:  # the thread stopped without an error: a live source must not end
            raise FrameSourceError(f"{self.name}: the stream ended")
        return frame

    def close(self) -> None:
        """Stop the grabbing thread and release the capture (idempotent). A thread blocked in
        a read of a stalled stream is waited for up to the capture's read timeout (2 x
        ``timeout`` for network streams); after that it is left to end on its own."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=2.0 * self.timeout + 1.0)
        if not self._thread.is_alive():
            self._cap.release()
