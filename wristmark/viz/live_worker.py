"""The live view's drawing process (``python -m viz.live_worker ZMQ_URL``).

It runs apart from the servo loop so that drawing never competes with the loop for Python's
GIL. stdin carries first the pickled SceneConfig (8-byte little-endian length, then the bytes),
then fixed-size cycle records (viz.record_wire); for several arms in one view the pickled
viz.arms_scene.ArmsSceneConfig, then records that each name their arm (record_wire.encode_arm).
It draws the newest record (of each arm) at most ``--rate`` times a second as one batched ZMQ
request, with the trails of the last ``--trail`` seconds; it prints ``ready`` once the scene
is built, and at end of input (the parent closed the pipe or died) draws the last record,
prints its statistics as one JSON line and exits.
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
from collections.abc import Iterable

import meshcat
import numpy as np
from numpy.typing import NDArray

from wristmark.viz.arms_scene import ArmsScene, ArmsSceneConfig
from wristmark.viz.frame_pane import show_frame
from wristmark.viz.record_wire import ARM_RECORD_SIZE, RECORD_SIZE, WireRecord, decode, decode_arm
from wristmark.viz.scene import ROOT, ArmScene, SceneConfig, SceneState
from wristmark.viz.style import TIP_KINDS
from wristmark.viz.view_priority import lower_priority
from wristmark.viz.viewer_client import ZmqWindow

Array = NDArray[np.float64]

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


def trail_paths(trail: Iterable[WireRecord], t_now: float, seconds: float,
                kinds: Iterable[str] = TIP_KINDS) -> dict[str, Array]:
    """(N, 3) points [m] per tip kind of the records of the last ``seconds`` before ``t_now``,
    at most TRAIL_POINTS of them (the newest kept)."""
    recent = [r for r in trail if r.t >= t_now - seconds]
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
    return {k: paths[k] for k in kinds}


class Drawer:
    """Keeps the newest record and the trail, draws at most once per ``period`` [s]."""

    record_size = RECORD_SIZE  # [B] of one record on the pipe

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

    def take(self, data: bytes) -> None:
        """Take one record as it came through the pipe (``record_size`` bytes)."""
        self.add(decode(data))

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
        with self.window.batch():
            self.scene.show(SceneState.from_record(rec))
            self.scene.set_trails(trail_paths(self.trail, rec.t, self.trail_seconds))
        self.drawn(t0, status_lines(rec))

    def drawn(self, t0: float, status: dict[str, str]) -> None:
        """After a frame begun at ``t0`` (monotonic [s]): send ``status`` (at most every
        STATUS_PERIOD) and count the frame."""
        if t0 - self.last_status >= STATUS_PERIOD:
            self.window.send_status(status)
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


class ArmsDrawer(Drawer):
    """The drawer of a scene of several arms: the newest record and the trail of each arm
    (records: record_wire.encode_arm), all arms drawn in one batched request per frame."""

    record_size = ARM_RECORD_SIZE

    def __init__(self, scene: ArmsScene, window: ZmqWindow, period: float, trail_seconds: float) -> None:
        self.arms = scene
        self.names = scene.config.names
        super().__init__(scene.parts[self.names[0]], window, period, trail_seconds)
        self.latest_of: dict[str, WireRecord] = {}
        self.trail_of: dict[str, deque[WireRecord]] = {n: deque(maxlen=TRAIL_MAX) for n in self.names}

    def take(self, data: bytes) -> None:
        """Take one arm's record (an unknown arm index is ignored)."""
        index, rec = decode_arm(data)
        if index >= len(self.names):
            return
        name = self.names[index]
        last = self.latest_of.get(name)
        if last is not None and rec.t < last.t:
            self.trail_of[name].clear()
        self.latest_of[name] = self.latest = rec
        self.trail_of[name].append(rec)
        self.pending = True
        self.records += 1

    def draw(self) -> None:
        """Send every arm's newest record and trails (one batched request, plus the status)."""
        if not self.latest_of:
            return
        t0 = time.monotonic()
        with self.window.batch():
            for name, rec in self.latest_of.items():
                part = self.arms.parts[name]
                part.show(SceneState.from_record(rec))
                part.set_trails(trail_paths(self.trail_of[name], rec.t, self.trail_seconds, part.tip_kinds))
        self.drawn(t0, arms_status_lines(self.latest_of))


def arms_status_lines(latest: dict[str, WireRecord]) -> dict[str, str]:
    """Short status of several arms' newest cycles: the clock and phase, then per arm its errors."""
    recs = list(latest.values())
    newest = max(recs, key=lambda r: r.t)
    out = {"t": f"{newest.t:7.2f} s", "phase": newest.phase}
    for name, rec in latest.items():
        for key, value in status_lines(rec).items():
            if key not in ("t", "phase"):
                out[f"{name}: {key}"] = value
    return out


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
        size = drawer.record_size
        n = len(buf) // size
        for i in range(n):
            drawer.take(buf[i * size:(i + 1) * size])
        buf = buf[n * size:]
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
    if not isinstance(config, SceneConfig | ArmsSceneConfig):
        raise TypeError("the first message must be a SceneConfig or an ArmsSceneConfig")
    window = ZmqWindow(args.zmq_url, "")
    vis = meshcat.Visualizer(window=window)
    drawer: Drawer
    if isinstance(config, ArmsSceneConfig):
        with window.batch():
            arms = ArmsScene(vis, config)
            arms.show({n: SceneState.at_rest(c.params) for n, c in config.arms.items()})
        drawer = ArmsDrawer(arms, window, 1.0 / args.rate, args.trail)
    else:
        with window.batch():
            scene = ArmScene(vis, config)
            scene.show(SceneState.at_rest(config.params))
        drawer = Drawer(scene, window, 1.0 / args.rate, args.trail, args.image, 1.0 / args.image_rate)
    print("ready", flush=True)
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
