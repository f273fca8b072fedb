"""Network stereo streams (``http://...`` MJPEG, ``rtsp://...``) through OpenCV's FFmpeg
backend, read by a grabbing thread that keeps the newest frame (cvs.frame_source_live).

Low delay: unless the user set ``OPENCV_FFMPEG_CAPTURE_OPTIONS`` themselves, FFmpeg is asked
not to buffer (``fflags;nobuffer|flags;low_delay``), to probe little before the first frame
(``probesize``, ``analyzeduration``) and to carry RTSP over TCP. The open and read timeouts
(``CAP_PROP_OPEN_TIMEOUT_MSEC``, ``CAP_PROP_READ_TIMEOUT_MSEC``) make a stream that never
starts fail within ``timeout`` s and end a blocked read of a stalled one.
"""

from __future__ import annotations

import os
import threading

import cv2

from cvs.frame_source_live import LiveCaptureSource
from cvs.frames import FrameSourceError

LOW_DELAY_OPTIONS = "fflags;nobuffer|flags;low_delay|probesize;65536|analyzeduration;0|rtsp_transport;tcp"
_ENV = "OPENCV_FFMPEG_CAPTURE_OPTIONS"
_ENV_LOCK = threading.Lock()


def is_stream_url(spec: str) -> bool:
    """True for the network SPECs: http://, https://, rtsp://, rtsps://."""
    return spec.split("://", 1)[0].lower() in ("http", "https", "rtsp", "rtsps") and "://" in spec


def open_network_stream(url: str, layout: str = "sbs", timeout: float = 5.0) -> LiveCaptureSource:
    """Open ``url`` (fails within about ``timeout`` s [s] when nothing arrives) as a live source."""
    ms = max(int(1e3 * timeout), 1)
    params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms]
    with _ENV_LOCK:
        user_set = _ENV in os.environ
        if not user_set:
            os.environ[_ENV] = LOW_DELAY_OPTIONS
        try:
            cap = cv2.VideoCapture(url, cv2.CAP_FFMPEG, params)
        except cv2.error as e:
            raise FrameSourceError(f"{url}: cannot open the stream ({str(e).strip().splitlines()[-1]})") from e
        finally:
            if not user_set:
                del os.environ[_ENV]
    if not cap.isOpened():
        cap.release()
        raise FrameSourceError(f"{url}: cannot open the stream (no video within {timeout:g} s, or not reachable)")
    return LiveCaptureSource(cap, url, layout, timeout)
