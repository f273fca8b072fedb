"""cvs.sources.mjpeg_server: a real multipart/x-mixed-replace stream over loopback, read by a raw
socket client and by OpenCV's FFmpeg backend."""

from __future__ import annotations

import socket
import threading
import time

import cv2
import numpy as np
import pytest

from wristmark.cvs.sources.mjpeg_server import BOUNDARY, MjpegServer

pytestmark = [pytest.mark.network]


def _read_parts(host: str, port: int, n: int, timeout: float = 5.0) -> tuple[bytes, list[bytes]]:
    """HTTP GET, then the first ``n`` JPEG parts of the multipart body."""
    with socket.create_connection((host, port), timeout=timeout) as s:
        s.sendall(b"GET /stream.mjpg HTTP/1.1\r\nHost: x\r\n\r\n")
        buf = b""
        while b"\r\n\r\n" not in buf:
            buf += s.recv(65536)
        head, buf = buf.split(b"\r\n\r\n", 1)
        parts: list[bytes] = []
        while len(parts) < n:
            while b"\r\n\r\n" not in buf:
                buf += s.recv(65536)
            part_head, buf = buf.split(b"\r\n\r\n", 1)
            assert part_head.startswith(f"--{BOUNDARY}".encode())
            length = int(next(line.split(b":")[1] for line in part_head.split(b"\r\n")
                              if line.lower().startswith(b"content-length")))
            while len(buf) < length + 2:
                buf += s.recv(65536)
            parts.append(buf[:length])
            buf = buf[length + 2 :]
        return head, parts


def test_parts_are_the_published_jpegs() -> None:
    with MjpegServer() as srv:
        assert srv.url.startswith("http://127.0.0.1:") and srv.port > 0
        jpegs = [cv2.imencode(".jpg", np.full((40, 60, 3), 30 * k, np.uint8))[1].tobytes() for k in range(3)]
        result: dict[str, object] = {}

        def client() -> None:
            result["head"], result["parts"] = _read_parts(srv.host, srv.port, 3)

        th = threading.Thread(target=client)
        th.start()
        deadline = time.monotonic() + 10.0
        while srv.clients == 0 and time.monotonic() < deadline:  # until connected and waiting
            time.sleep(0.01)
        assert srv.clients == 1  # nothing is published yet
        for j in jpegs:
            srv.publish(j)
            time.sleep(0.1)
        th.join(timeout=5)
        assert b"multipart/x-mixed-replace" in result["head"]  # type: ignore[operator]
        assert result["parts"] == jpegs


def test_publish_image_and_opencv_reads_it() -> None:
    with MjpegServer() as srv:
        img = np.zeros((120, 160, 3), np.uint8)
        img[:, 80:] = 200
        stop = threading.Event()

        def publisher() -> None:
            while not stop.is_set():
                srv.publish_image(img, quality=90)
                time.sleep(0.02)

        th = threading.Thread(target=publisher, daemon=True)
        th.start()
        cap = cv2.VideoCapture(srv.url, cv2.CAP_FFMPEG, [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, 5000])
        try:
            ok, got = cap.read()
        finally:
            cap.release()
            stop.set()
            th.join()
        assert ok and got.shape == img.shape
        assert np.abs(got.astype(int) - img).mean() < 3


def test_close_ends_streams_and_bad_quality() -> None:
    srv = MjpegServer()
    with pytest.raises(ValueError, match="quality"):
        srv.publish_image(np.zeros((8, 8), np.uint8), quality=0)
    srv.close()
    srv.close()  # idempotent
    with pytest.raises(OSError):
        socket.create_connection((srv.host, srv.port), timeout=1).recv(1)
