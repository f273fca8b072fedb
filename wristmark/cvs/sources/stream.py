"""Network stereo streams (``http://...`` MJPEG, ``rtsp://...``) through OpenCV's FFmpeg
backend, read by a grabbing thread that keeps the newest frame (cvs.sources.live).

Low delay: unless the user set ``OPENCV_FFMPEG_CAPTURE_OPTIONS`` themselves, FFmpeg is asked
not to buffer (``fflags;nobuffer|flags;low_delay``), to probe little before the first frame
(``probesize``, ``analyzeduration``) and to carry RTSP over TCP. The open and read timeouts
(``CAP_PROP_OPEN_TIMEOUT_MSEC`` = ``timeout``, ``CAP_PROP_READ_TIMEOUT_MSEC`` = twice that)
make a stream that never starts fail within ``timeout`` s and end a blocked read of a stalled
one after the live source has reported the stall.

MJPEG streams are read as JPEG packets (``CAP_PROP_FORMAT = -1``) and decoded here: grey
decoding then reads only the luma plane, and a capture time the sender put in the JPEG
(cvs.sources.jpeg_stamp, e.g. cvs.sources.mjpeg_server.MjpegServer.publish(jpeg, t_capture)) becomes the
frame's ``t_capture``; without one, ``t_capture`` is the arrival time.
"""

from __future__ import annotations

import os
import threading

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError
from wristmark.cvs.sources.jpeg_stamp import read_capture_stamp
from wristmark.cvs.sources.live import Decode, LiveCaptureSource

LOW_DELAY_OPTIONS = "fflags;nobuffer|flags;low_delay|probesize;65536|analyzeduration;0|rtsp_transport;tcp"
_ENV = "OPENCV_FFMPEG_CAPTURE_OPTIONS"
_ENV_LOCK = threading.Lock()


def is_stream_url(spec: str) -> bool:
    """True for the network SPECs: http://, https://, rtsp://, rtsps://."""
    return spec.split("://", 1)[0].lower() in ("http", "https", "rtsp", "rtsps") and "://" in spec


def jpeg_decoder(source: str, grayscale: bool) -> Decode:
    """A packet decoder for MJPEG streams read as JPEG packets: the image (grey or BGR) and
    the capture time the sender put in the JPEG (cvs.sources.jpeg_stamp), if any."""
    flag = cv2.IMREAD_GRAYSCALE if grayscale else cv2.IMREAD_COLOR

    def decode(packet: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], float | None]:
        img = cv2.imdecode(packet, flag)
        if img is None:
            raise FrameSourceError(f"{source}: a frame of the stream is not a decodable JPEG")
        return np.asarray(img), read_capture_stamp(packet.tobytes()[:4096])

    return decode


def open_network_stream(url: str, layout: str = "sbs", timeout: float = 5.0, grayscale: bool = False
                        ) -> LiveCaptureSource:
    """Open ``url`` (fails within about ``timeout`` s [s] when nothing arrives) as a live source;
    grayscale: decode MJPEG frames to grey (only the luma plane)."""
    ms = max(int(1e3 * timeout), 1)
    # FFmpeg's read timeout is twice ours, so that a stall is reported as one (by the live
    # source's wait), not as the end of the stream (a read that FFmpeg gave up)
    params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, 2 * ms]
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
    decode = None
    if int(cap.get(cv2.CAP_PROP_FOURCC)) == cv2.VideoWriter.fourcc(*"MJPG") and cap.set(cv2.CAP_PROP_FORMAT, -1):
        decode = jpeg_decoder(url, grayscale)  # JPEG packets: our decoder, and the sender's capture time
    return LiveCaptureSource(cap, url, layout, timeout, decode=decode)
