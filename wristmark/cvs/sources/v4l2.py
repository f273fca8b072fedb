"""Live V4L2/UVC stereo cameras (``/dev/videoN`` or ``device:N``) delivering side-by-side (or
top-bottom) frames, read by a grabbing thread that keeps the newest frame
(cvs.sources.live).

The pixel format is set before the size (UVC cameras offer large sizes at a usable rate only
in MJPG): FOURCC, then width and height (``size``), then the frame rate (``fps``). A camera
that does not deliver the size asked for is an error naming both. ``t_capture`` is the V4L2
buffer's timestamp (``CAP_PROP_POS_MSEC``, the kernel's CLOCK_MONOTONIC for UVC devices, the
same clock as ``time.monotonic()``) when it lies within a second before the frame's arrival,
else the arrival time.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import cv2

from wristmark.cvs.sources.frames import FrameSourceError
from wristmark.cvs.sources.live import LiveCaptureSource

_DEVICE = re.compile(r"^(?:/dev/video(\d+)|device:(\d+))$")


def is_device_spec(spec: str) -> bool:
    """True for ``/dev/videoN`` and ``device:N``."""
    return _DEVICE.match(spec) is not None


def device_stamp(cap: cv2.VideoCapture, t_arrival: float) -> float:
    """The frame's V4L2 buffer time [s] (CAP_PROP_POS_MSEC); the live source keeps it only
    when it is plausible (cvs.sources.live.plausible_stamp)."""
    return 1e-3 * float(cap.get(cv2.CAP_PROP_POS_MSEC))


def open_v4l2_device(spec: str, layout: str = "sbs", size: tuple[int, int] | None = None,
                     fps: float | None = None, fourcc: str | None = "MJPG", timeout: float = 5.0) -> LiveCaptureSource:
    """Open a camera SPEC; size: (width, height) of the whole frame [px]; fps [1/s]; fourcc:
    four-character pixel format (None: the camera's default)."""
    m = _DEVICE.match(spec)
    if m is None:
        raise FrameSourceError(f"'{spec}' is not a camera (expected /dev/videoN or device:N)")
    number = int(m.group(1) or m.group(2))
    path = Path(f"/dev/video{number}")
    if sys.platform.startswith("linux") and not path.exists():
        raise FrameSourceError(f"{spec}: no such camera ({path} does not exist)")
    if fourcc is not None and len(fourcc) != 4:
        raise FrameSourceError(f"--fourcc must be four characters (e.g. MJPG), got '{fourcc}'")
    backend = cv2.CAP_V4L2 if sys.platform.startswith("linux") else cv2.CAP_ANY
    cap = cv2.VideoCapture(number, backend)
    if not cap.isOpened():
        cap.release()
        raise FrameSourceError(f"{spec}: cannot open the camera (busy, no permission, or not a capture device)")
    if fourcc is not None:
        cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*fourcc))
    if size is not None:
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, int(size[0]))
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, int(size[1]))
    if fps is not None:
        cap.set(cv2.CAP_PROP_FPS, float(fps))
    if size is not None:
        got = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if got != (int(size[0]), int(size[1])):
            cap.release()
            raise FrameSourceError(f"{spec}: asked for {size[0]}x{size[1]} px, the camera delivers {got[0]}x{got[1]}")
    return LiveCaptureSource(cap, spec, layout, timeout, stamp=device_stamp)
