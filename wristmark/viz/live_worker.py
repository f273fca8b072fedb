"""The live view's drawing process (``python -m viz.live_worker ZMQ_URL``).

It runs apart from the servo loop so that drawing never competes with the loop for Python's
GIL. stdin carries first the pickled SceneConfig (8-byte little-endian length, then the bytes),
then fixed-size cycle records (viz.record_wire). It draws the newest record at most
``--rate`` times a second as one batched ZMQ request, with the trails of the last
``--trail`` seconds; it prints ``ready`` once the scene is built, and at end of input (the
parent closed the pipe or died) draws the last record, prints its statistics as one JSON line
and exits.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import select
import sys
import time
from collections import deque

import meshcat
import numpy as np

from wristmark.viz.frame_pane import show_frame
from wristmark.viz.record_wire import RECORD_SIZE, WireRecord, decode
from wristmark.viz.scene import ROOT, ArmScene, SceneConfig, SceneState
from wristmark.viz.style import TIP_KINDS
from wristmark.viz.view_priority import lower_priority
from wristmark.viz.viewer_client import ZmqWindow

STATUS_PERIOD = 0.2  # [s] between status-line updates
TRAIL_MAX = 4000  # cycles kept for the trails
TRAIL_POINTS = 200  # points per trail line at most


def _read_exact(fd: int, n: int) -> bytes:
    out = b""
    while len(out) < n:
        chunk = os.read(fd, n - len(out))
        if not chunk:
            raise EOFError("input closed before the scene configuration arrived")
        out += chunk
    return out


def status_lines(rec: WireRecord) -> dict[str, str]:
    """Short status of one cycle for the page's status block (errors in mm)."""
    err = 1000.0 * float(np.linalg.norm(rec.p_true - rec.p_des))
    out = {"t": f"{rec.t:7.2f} s", "phase": rec.phase, "|true - desired|": f"{err:6.2f} mm"}
    if rec.p_est is not None:
        out["|estimate - true|"] = f"{1000.0 * float(np.linalg.norm(rec.p_est - rec.p_true)):6.2f} mm"
    elif "closed" in rec.phase:
        out["|estimate - true|"] = "no estimate"
    return out


class Drawer:
    """Keeps the newest record and the trail, draws at most once per ``period`` [s]."""

    def __init__(self, scene: ArmScene, window: ZmqWindow, period: float, trail_seconds: float,
                 image: str | None = None, image_period: float = 0.5) -> None:
        self.scene = scene
        self.image = image
        self.image_period = image_period
        self._image_mtime = 0
        self._next_image = 0.0
        self.images = 0
        self.window = window
        self.period = period
        self.trail_seconds = trail_seconds
        self.latest: WireRecord | None = None
        self.trail: deque[WireRecord] = deque(maxlen=TRAIL_MAX)
        self.pending = False
        self.next_frame = 0.0
        self.last_status = -1e9
        self.records = 0
        self.frames = 0
        self.draw_s = 0.0
        self.first = self.last = 0.0

    def add(self, rec: WireRecord) -> None:
        """Take one record (a clock that goes back starts a new trail)."""
        if self.latest is not None and rec.t < self.latest.t:
            self.trail.clear()
        self.latest = rec
        self.trail.append(rec)
        self.pending = True
        self.records += 1

    def draw(self) -> None:
        """Send the newest record and the trails (one batched request, plus the status)."""
        rec = self.latest
        if rec is None:
            return
        t0 = time.monotonic()
        t_min = rec.t - self.trail_seconds
        recent = [r for r in self.trail if r.t >= t_min]
        step = -(-len(recent) // TRAIL_POINTS)  # a fast simulated loop logs thousands of cycles
        recent = recent[::-1][::step][::-1]  # keeps the newest
        nan3 = np.full(3, np.nan)
        paths = {
            "desired": np.array([r.p_des for r in recent]),
            "commanded": np.array([r.p_cmd for r in recent]),
            "estimated": np.array([r.p_est if r.p_est is not None else nan3 for r in recent]),
            "true": np.array([r.p_true for r in recent]),
        }
        assert set(paths) == set(TIP_KINDS)
        with self.window.batch():
            self.scene.show(SceneState.from_record(rec))
            self.scene.set_trails(paths)
        if t0 - self.last_status >= STATUS_PERIOD:
            self.window.send_status(status_lines(rec))
            self.last_status = t0
        t1 = time.monotonic()
        if self.frames == 0:
            self.first = t1
        self.last = t1
        self.frames += 1
        self.draw_s += t1 - t0
        self.pending = False
        self.next_frame = t0 + self.period

    def show_image(self) -> None:
        """Upload the camera image when its file changed (at most once per image period)."""
        now = time.monotonic()
        if self.image is None or now < self._next_image or self.scene.config.camera is None:
            return
        try:
            mtime = os.stat(self.image).st_mtime_ns
        except FileNotFoundError:
            return
        if mtime == self._image_mtime:
            return
        with open(self.image, "rb") as f:
            png = f.read()
        self._image_mtime = mtime
        self._next_image = now + self.image_period
        show_frame(self.scene.vis, ROOT, self.scene.config.camera, png)
        self.images += 1

    def stats(self) -> dict[str, float]:
        """Records received, frames drawn, frame rate [Hz], mean frame time [ms]."""
        span = self.last - self.first
        return {
            "records": self.records,
            "frames": self.frames,
            "frame_rate_hz": (self.frames - 1) / span if self.frames > 1 and span > 0 else 0.0,
            "mean_draw_ms": 1000.0 * self.draw_s / self.frames if self.frames else 0.0,
            "images": self.images,
        }


def serve(fd: int, drawer: Drawer) -> None:
    """Read records from ``fd`` until end of input and draw at the drawer's rate. Between
    frames it sleeps and lets records pile up in the pipe, so the loop's writes wake nobody."""
    os.set_blocking(fd, False)
    buf = b""
    eof = False
    while not eof:
        delay = drawer.next_frame - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        if not drawer.pending:
            select.select([fd], [], [], drawer.image_period if drawer.image else 1.0)
        while True:
            try:
                chunk = os.read(fd, 1 << 16)
            except BlockingIOError:
                break
            if not chunk:
                eof = True
                break
            buf += chunk
        n = len(buf) // RECORD_SIZE
        for i in range(n):
            drawer.add(decode(buf[i * RECORD_SIZE:(i + 1) * RECORD_SIZE]))
        buf = buf[n * RECORD_SIZE:]
        if drawer.pending:
            drawer.draw()
        drawer.show_image()


def main(argv: list[str] | None = None) -> int:
    """Entry point of the drawing process."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("zmq_url")
    ap.add_argument("--rate", type=float, default=30.0, help="frames per second at most [Hz]")
    ap.add_argument("--trail", type=float, default=6.0, help="trail length [s]")
    ap.add_argument("--image", help="PNG file of the latest left camera image (written by the loop's process)")
    ap.add_argument("--image-rate", type=float, default=2.0, help="camera images shown per second at most [Hz]")
    args = ap.parse_args(argv)
    lower_priority()
    fd = sys.stdin.buffer.fileno()
    (size,) = np.frombuffer(_read_exact(fd, 8), "<u8")
    config = pickle.loads(_read_exact(fd, int(size)))
    if not isinstance(config, SceneConfig):
        raise TypeError("the first message must be a SceneConfig")
    window = ZmqWindow(args.zmq_url, "")
    vis = meshcat.Visualizer(window=window)
    with window.batch():
        scene = ArmScene(vis, config)
        scene.show(SceneState.at_rest(config.params))
    print("ready", flush=True)
    drawer = Drawer(scene, window, 1.0 / args.rate, args.trail, args.image, 1.0 / args.image_rate)
    try:
        serve(fd, drawer)
    except Exception as e:  # noqa: BLE001 - one line; the loop goes on without its view
        print(f"wristmark live view stopped: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
        return 1
    finally:
        print(json.dumps(drawer.stats()), flush=True)
        window.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
