"""A live HTTP MJPEG stream on 127.0.0.1 (cvs.sources.mjpeg_server) read by cvs.sources.stream:
newest-frame semantics, a stall mid-run, a stream that never starts."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from wristmark.cvs.sources.frames import FrameSourceError
from wristmark.cvs.sources.layout import join_stereo
from wristmark.cvs.sources.mjpeg_server import MjpegServer
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source

pytestmark = [pytest.mark.network, pytest.mark.wallclock]

FPS = 40.0


class Publisher:
    """Publishes side-by-side frames whose views carry ids 2k, 2k+1, at FPS, for ``n`` frames
    (None: until stopped); ``times[k]`` is when frame k was published (time.monotonic)."""

    def __init__(self, server: MjpegServer, id_view: Callable[..., np.ndarray], n: int | None = None) -> None:
        self.server, self.id_view, self.n = server, id_view, n
        self.times: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        k, t0 = 0, time.monotonic()
        while not self._stop.is_set() and (self.n is None or k < self.n):
            img = join_stereo(self.id_view(k, 0), self.id_view(k, 1))
            self.times.append(time.monotonic())
            self.server.publish_image(img, quality=85)
            k += 1
            self._stop.wait(max(t0 + k / FPS - time.monotonic(), 0.0))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


@pytest.fixture
def server() -> Iterator[MjpegServer]:
    with MjpegServer() as srv:
        yield srv


def test_slow_consumer_gets_the_newest_frame(server: MjpegServer, frame_ids: tuple) -> None:
    id_view, read_id = frame_ids
    pub = Publisher(server, id_view)
    src = open_stereo_source(server.url, SourceOptions(timeout=5.0, image_size=(320, 180)))
    processing = 0.06  # [s] the consumer's "work" per frame: 2.4 periods
    ages, ids = [], []
    try:
        src.read()  # connected and flowing
        for _ in range(12):
            f = src.read()
            assert f is not None
            k = read_id(f.left) // 2
            assert read_id(f.right) == 2 * k + 1  # split: both views of the same frame
            ages.append(time.monotonic() - pub.times[k])  # age of the content when it is processed
            ids.append(k)
            time.sleep(processing)
        dropped = src.dropped
    finally:
        src.close()
        pub.stop()
    # never older than one period plus the processing time (plus transport on a loaded machine)
    assert max(ages) < 1.0 / FPS + processing + 0.03, ages
    assert all(b > a for a, b in zip(ids, ids[1:]))
    assert dropped >= 12  # ~1.4 frames dropped per processed one


def test_stall_mid_run_is_one_line_error_within_timeout(server: MjpegServer, frame_ids: tuple) -> None:
    pub = Publisher(server, frame_ids[0], n=10)
    src = open_stereo_source(server.url, SourceOptions(timeout=1.0))
    got = 0
    t_last = time.monotonic()
    try:
        with pytest.raises(FrameSourceError) as e:
            while True:
                src.read()
                got += 1
                t_last = time.monotonic()
        waited = time.monotonic() - t_last
    finally:
        src.close()
        pub.stop()
    msg = str(e.value)
    assert got >= 3 and "\n" not in msg and server.url in msg and "stalled" in msg
    assert 0.9 < waited < 2.0


def test_stream_that_never_starts(server: MjpegServer) -> None:
    t0 = time.monotonic()
    with pytest.raises(FrameSourceError) as e:
        open_stereo_source(server.url, SourceOptions(timeout=1.0))  # headers, never a frame
    assert time.monotonic() - t0 < 3.0
    assert server.url in str(e.value) and "\n" not in str(e.value)


def test_nobody_listening() -> None:
    with socket.socket() as s:  # a port that was free a moment ago and has no listener
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/stream.mjpg"
    t0 = time.monotonic()
    with pytest.raises(FrameSourceError, match="cannot open the stream"):
        open_stereo_source(url, SourceOptions(timeout=1.0))
    assert time.monotonic() - t0 < 3.0


def test_server_closing_ends_the_stream_with_an_error(server: MjpegServer, frame_ids: tuple) -> None:
    pub = Publisher(server, frame_ids[0])
    src = open_stereo_source(server.url, SourceOptions(timeout=2.0))
    try:
        assert src.read() is not None
        pub.stop()
        server.close()
        with pytest.raises(FrameSourceError) as e:
            while True:
                src.read()
    finally:
        src.close()
    assert server.url in str(e.value) and "\n" not in str(e.value)


def test_sender_capture_time_and_grey_decoding(server: MjpegServer, frame_ids: tuple) -> None:
    """Frames published with their capture time (as the virtual lab's camera does) carry it to
    t_capture; grey decoding reads only the luma plane."""
    id_view, read_id = frame_ids
    stamps: dict[int, float] = {}
    stop = threading.Event()

    def publish() -> None:
        k = 0
        while not stop.is_set():
            t_cap = time.monotonic() - 0.02  # "exposed" 20 ms before it is sent
            stamps[k] = t_cap
            server.publish_image(join_stereo(id_view(k, 0), id_view(k, 1)), 85, t_capture=t_cap)
            k += 1
            stop.wait(1 / FPS)

    th = threading.Thread(target=publish, daemon=True)
    th.start()
    src = open_stereo_source(server.url, SourceOptions(timeout=5.0, grayscale=True, image_size=(320, 180)))
    try:
        got = [src.read() for _ in range(5)]
    finally:
        src.close()
        stop.set()
        th.join()
    for f in got:
        assert f is not None and f.left.ndim == 2 and f.left.shape == (180, 320)
        k = read_id(f.left) // 2
        assert f.t_capture == pytest.approx(stamps[k], abs=2e-6)
