"""An MJPEG-over-HTTP server: JPEG frames as one ``multipart/x-mixed-replace`` stream.

``MjpegServer(host, port)`` listens (loopback by default; ``port=0`` lets the OS choose) in a
daemon thread of :class:`http.server.ThreadingHTTPServer`. Every GET gets the stream: the
current frame at once, then every newer one, each part ``--BOUNDARY``, ``Content-Type:
image/jpeg``, ``Content-Length`` and the JPEG bytes, which OpenCV's FFmpeg backend (the
``mpjpeg`` demuxer), browsers and ``curl`` read. ``publish(jpeg, t_capture=None)`` hands a new
frame to every client; with ``t_capture`` the frame's ``time.monotonic()`` capture time travels
inside the JPEG (cvs.sources.jpeg_stamp). A client slower than the publisher skips to the newest frame
(nothing queues up). ``close()`` stops the server and ends every client's stream.

Used by the tests of the network frame source and by the virtual lab's camera.
"""

from __future__ import annotations

import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.jpeg_stamp import add_capture_stamp
from wristmark.models.errors import InputError

BOUNDARY = "wristmarkframe"
_POLL_S = 0.2  # how often a waiting client looks at the stop flag [s]


class _Handler(BaseHTTPRequestHandler):
    server: _Server

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the stdlib's name
        """Quiet: no access log on stderr."""

    def do_GET(self) -> None:  # noqa: N802 - the stdlib's name
        owner = self.server.owner
        self.send_response(200)
        self.send_header("Content-Type", f"multipart/x-mixed-replace; boundary={BOUNDARY}")
        self.send_header("Cache-Control", "no-cache, no-store")
        self.send_header("Connection", "close")
        self.end_headers()
        seen = max(owner.frame_count - 1, 0)  # start with the current frame, if there is one
        owner.count_client(+1)
        try:
            while True:
                jpeg, seen = owner.wait_frame(seen)
                if jpeg is None:
                    return
                head = f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpeg)}\r\n\r\n"
                self.wfile.write(head.encode("ascii") + jpeg + b"\r\n")
                self.wfile.flush()
        except (BrokenPipeError, ConnectionResetError, OSError):
            return  # the client went away
        finally:
            owner.count_client(-1)


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True
    owner: MjpegServer


class MjpegServer:
    """Serve published JPEG frames as an MJPEG stream at :attr:`url` (see the module docstring).

    host: address to bind (default 127.0.0.1: loopback only); port: TCP port (0: chosen by the
    OS, read it from :attr:`port` or :attr:`url`); path: the stream's URL path."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, path: str = "/stream.mjpg") -> None:
        self._cond = threading.Condition()
        self._jpeg: bytes | None = None
        self._count = 0
        self._clients = 0
        self._closed = False
        try:
            self._httpd = _Server((host, int(port)), _Handler)
        except OSError as e:
            raise InputError(f"cannot serve MJPEG on {host}:{port}: {e.strerror or e}") from e
        self._httpd.owner = self
        self.host = host
        self.port = int(self._httpd.server_address[1])
        self.path = path if path.startswith("/") else "/" + path
        self._thread = threading.Thread(target=self._httpd.serve_forever, name="mjpeg-server", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        """The stream's URL, e.g. ``http://127.0.0.1:PORT/stream.mjpg`` (any path is served)."""
        return f"http://{self.host}:{self.port}{self.path}"

    @property
    def frame_count(self) -> int:
        """Frames published so far."""
        return self._count

    @property
    def clients(self) -> int:
        """Clients receiving the stream now."""
        return self._clients

    def count_client(self, change: int) -> None:
        """A client connected (+1) or left (-1)."""
        with self._cond:
            self._clients += change

    def publish(self, jpeg: bytes, t_capture: float | None = None) -> None:
        """Hand one JPEG-encoded frame to every connected client (they skip to the newest);
        ``t_capture``: its capture time on this host's ``time.monotonic()`` [s], carried in
        the JPEG (cvs.sources.jpeg_stamp) for the network frame source to read."""
        data = bytes(jpeg) if t_capture is None else add_capture_stamp(bytes(jpeg), t_capture)
        with self._cond:
            self._jpeg = data
            self._count += 1
            self._cond.notify_all()

    def publish_image(self, image: NDArray[np.uint8], quality: int = 90, t_capture: float | None = None) -> int:
        """JPEG-encode an 8-bit image (grey or BGR) at ``quality`` (1-100) and publish it
        (``t_capture`` as in :meth:`publish`); returns the JPEG's size [bytes]."""
        import cv2

        if not 1 <= int(quality) <= 100:
            raise InputError(f"JPEG quality must be in 1..100, got {quality}")
        ok, buf = cv2.imencode(".jpg", np.asarray(image), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
        if not ok:
            raise InputError(f"cannot JPEG-encode an image of shape {np.shape(image)}")
        data = buf.tobytes()
        self.publish(data, t_capture)
        return len(data)

    def wait_frame(self, seen: int) -> tuple[bytes | None, int]:
        """Block until a frame newer than number ``seen`` exists; returns it and its number
        (None once the server is closed)."""
        with self._cond:
            while self._count == seen and not self._closed:
                self._cond.wait(_POLL_S)
            if self._closed:
                return None, seen
            return self._jpeg, self._count

    def close(self) -> None:
        """Stop serving and end every client's stream (idempotent)."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._cond.notify_all()
        self._httpd.shutdown()
        self._httpd.server_close()
        self._thread.join(timeout=2.0)

    def __enter__(self) -> MjpegServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
