"""Live 3D view of a running servo loop, fed by its ``on_cycle`` hook without slowing it down.

``on_cycle(rec)`` packs the cycle into 224 bytes and writes them to a non-blocking pipe (a few
microseconds; a full pipe drops the record rather than wait). A separate drawing process
(viz.live_worker) draws the newest record at most ``rate_hz`` times a second, each frame one
batched request to the Meshcat server process: the loop never waits for the browser, the
server or the drawing, and never shares Python's GIL with them. Frames: {w} world, metres.

Use::

    view = start_live_view(setup)              # prints the URL to open
    loop.on_cycle = view.on_cycle              # rig.loop.servo_loop.ServoLoop
    loop.on_frame = view.on_frame              # the left camera image with its corners (2 Hz)
    ...                                        # run the loop
    view.close()                               # or view.hold() first, to keep serving

Several arms in one view: ``start_scene_live_view(scene_setup)`` and its ``on_arm_cycle(name,
rec)`` as sim.several_arms.walk_scene's ``on_cycle``.
"""

from __future__ import annotations

import fcntl
import functools
import json
import os
import pickle
import select
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from wristmark.models.arm_spec import arm_size
from wristmark.models.errors import WristmarkError
from wristmark.viz.arms_scene import ArmsSceneConfig, ArmsSetup
from wristmark.viz.record_wire import MAX_PSI, encode, encode_arm
from wristmark.viz.scene import SceneConfig
from wristmark.viz.viewer_client import MeshcatServer, ViewerError

if TYPE_CHECKING:
    from wristmark.rig.loop.loop_setup import LoopSetup
    from wristmark.rig.recording.run_log import CycleRecord

DEFAULT_RATE_HZ = 30.0  # [Hz] frames sent to the browser at most
DEFAULT_IMAGE_RATE_HZ = 2.0  # [Hz] camera images shown at most
DEFAULT_TRAIL_SECONDS = 6.0  # [s] of recent tip paths drawn
PIPE_BYTES = 1 << 20  # [B] pipe to the drawing process
WORKER_STARTUP_TIMEOUT = 60.0  # [s] to import Pinocchio and build the scene on a loaded machine


@dataclass
class LiveStats:
    """Counters of a live view. Loop side: records sent and dropped (pipe full), time spent in
    on_cycle [us]. Drawing side (filled by close()): frames drawn, frame rate [Hz], mean frame
    time [ms], records received, camera images shown."""

    sent: int = 0
    dropped: int = 0
    on_cycle_us_total: float = 0.0
    frames: int = 0
    frame_rate_hz: float = 0.0
    mean_draw_ms: float = 0.0
    received: int = 0
    images: int = 0
    error: str = ""

    @property
    def mean_on_cycle_us(self) -> float:
        """Mean time one on_cycle call took in the loop [us]."""
        n = self.sent + self.dropped
        return self.on_cycle_us_total / n if n else 0.0


class LiveView:
    """A served scene updated from servo-loop records; see the module docstring."""

    def __init__(self, server: MeshcatServer, worker: subprocess.Popen[bytes], image_path: Path | None = None,
                 image_rate_hz: float = DEFAULT_IMAGE_RATE_HZ) -> None:
        self.server = server
        self.url = server.url
        self.stats = LiveStats()
        self.image_path = image_path
        self.images = 0
        self._image_period = 1.0 / image_rate_hz
        self._next_image = 0.0
        self._image_busy = threading.Event()
        self._worker = worker
        assert worker.stdin is not None
        self._fd: int | None = worker.stdin.fileno()
        os.set_blocking(self._fd, False)
        try:  # room for ~4600 cycles between two frames (Linux; the default 64 KiB holds ~290)
            fcntl.fcntl(self._fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), PIPE_BYTES)
        except OSError:
            pass

    def on_cycle(self, rec: CycleRecord) -> None:
        """ServoLoop hook: hand the cycle to the drawing process (never blocks)."""
        self._send(encode, rec)

    def _send(self, pack: Callable[[CycleRecord], bytes], rec: CycleRecord) -> None:
        """Write ``pack(rec)`` to the drawing process's pipe; a full pipe drops it."""
        if self._fd is None:
            return
        t0 = time.perf_counter()
        try:
            os.write(self._fd, pack(rec))
            self.stats.sent += 1
        except BlockingIOError:
            self.stats.dropped += 1
        except (BrokenPipeError, OSError) as e:
            self.stats.error = f"drawing process gone: {e}"
            self._fd = None
        self.stats.on_cycle_us_total += 1e6 * (time.perf_counter() - t0)

    def on_frame(self, frame: Any, measurement: Any) -> None:
        """ServoLoop frame hook: show the left image with the detected corners, at most
        ``image_rate_hz`` times a second; the shrinking and PNG encoding run in a thread of
        their own, so the loop pays a few microseconds (a frame arriving while one is being
        encoded is skipped)."""
        now = time.monotonic()
        if self.image_path is None or now < self._next_image or self._image_busy.is_set():
            return
        self._next_image = now + self._image_period
        self._image_busy.set()
        corners = getattr(measurement, "corners_left", None)
        threading.Thread(target=self._write_image, args=(frame.left, corners), daemon=True).start()

    def _write_image(self, left: Any, corners: Any) -> None:
        from wristmark.viz.frame_pane import frame_png

        try:
            png = frame_png(left, corners)
            if png is not None and self.image_path is not None:
                tmp = self.image_path.with_suffix(".tmp")
                tmp.write_bytes(png)
                os.replace(tmp, self.image_path)  # the drawing process never reads half a file
                self.images += 1
        except Exception as e:  # noqa: BLE001 - the view is best effort; the loop goes on
            self.stats.error = self.stats.error or f"camera image: {type(e).__name__}: {e}"
        finally:
            self._image_busy.clear()

    def hold(self, seconds: float | None = None) -> None:
        """Keep serving (the page keeps the last frame) for ``seconds``; None: until Ctrl-C."""
        try:
            if seconds is None:
                while True:
                    time.sleep(0.5)
            else:
                time.sleep(max(0.0, seconds))
        except KeyboardInterrupt:
            pass

    def close(self) -> None:
        """Let the drawing process draw the last record and exit, then stop the server."""
        w = self._worker
        if w.stdin is not None and not w.stdin.closed:
            self._fd = None
            try:
                w.stdin.close()
            except OSError:
                pass
        if w.poll() is None:
            try:
                w.wait(timeout=10)
            except subprocess.TimeoutExpired:
                w.kill()
                w.wait()
        if w.stdout is not None and not w.stdout.closed:
            for line in w.stdout.read().decode(errors="replace").splitlines():
                if line.startswith("{"):
                    s = json.loads(line)
                    self.stats.frames = int(s["frames"])
                    self.stats.frame_rate_hz = float(s["frame_rate_hz"])
                    self.stats.mean_draw_ms = float(s["mean_draw_ms"])
                    self.stats.received = int(s["records"])
                    self.stats.images = int(s.get("images", 0))
            w.stdout.close()
        if w.returncode not in (0, None) and not self.stats.error:
            self.stats.error = f"drawing process exited with status {w.returncode}"
        self.server.close()
        if self.image_path is not None:
            for p in (self.image_path, self.image_path.with_suffix(".tmp")):
                p.unlink(missing_ok=True)
            try:
                self.image_path.parent.rmdir()
            except OSError:
                pass

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SceneLiveView(LiveView):
    """The live view of several arms in one view (sim.several_arms.walk_scene): pass its
    :meth:`on_arm_cycle` as the walk's ``on_cycle``."""

    def __init__(self, server: MeshcatServer, worker: subprocess.Popen[bytes], names: list[str]) -> None:
        super().__init__(server, worker)
        self.names = list(names)
        self._packers = {n: functools.partial(encode_arm, i) for i, n in enumerate(self.names)}

    def on_arm_cycle(self, name: str, rec: CycleRecord) -> None:
        """Hand arm ``name``'s cycle to the drawing process (never blocks; unknown arms: ignored)."""
        pack = self._packers.get(name)
        if pack is not None:
            self._send(pack, rec)


def _start_worker(server: MeshcatServer, config: SceneConfig | ArmsSceneConfig, rate_hz: float,
                  trail_seconds: float, image_path: Path | None = None,
                  image_rate_hz: float = DEFAULT_IMAGE_RATE_HZ) -> subprocess.Popen[bytes]:
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    args = [sys.executable, "-u", "-m", "wristmark.viz.live_worker", server.zmq_url,
            "--rate", repr(rate_hz), "--trail", repr(trail_seconds)]
    if image_path is not None:
        args += ["--image", str(image_path), "--image-rate", repr(image_rate_hz)]
    proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
    assert proc.stdin is not None and proc.stdout is not None
    blob = pickle.dumps(config)
    proc.stdin.write(len(blob).to_bytes(8, "little") + blob)
    proc.stdin.flush()
    deadline = time.monotonic() + WORKER_STARTUP_TIMEOUT
    fd = proc.stdout.fileno()
    got = b""
    while b"ready" not in got:
        left = deadline - time.monotonic()
        if left <= 0 or proc.poll() is not None:
            proc.kill()
            proc.wait()
            raise ViewerError("the live view's drawing process did not start (see its error above)")
        ready, _, _ = select.select([fd], [], [], min(left, 0.5))
        if ready:
            got += os.read(fd, 64)
    return proc


def start_live_view(setup: LoopSetup | None = None, *, config: SceneConfig | None = None,
                    title: str = "wristmark live view", rate_hz: float = DEFAULT_RATE_HZ,
                    trail_seconds: float = DEFAULT_TRAIL_SECONDS, stream: TextIO | None = sys.stderr,
                    host: str | None = None) -> LiveView:
    """Start the Meshcat server and the drawing process for the scene of ``setup`` (or
    ``config``; default: configs/) and return a :class:`LiveView`: pass its ``on_cycle`` to
    the ServoLoop, call ``close()`` at the end. Prints the URL to open on ``stream``. The page
    is served on loopback only unless ``host`` adds an address (viz.web_hosts)."""
    if not rate_hz > 0:
        raise WristmarkError(f"live view rate must be > 0 Hz, got {rate_hz}")
    if not trail_seconds >= 0:
        raise WristmarkError(f"trail length must be >= 0 s, got {trail_seconds}")
    if config is None:
        if setup is None:
            from wristmark.rig.loop.loop_setup import load_loop_setup

            setup = load_loop_setup()
        config = SceneConfig.from_setup(setup)
    n = arm_size(config.params)[0]
    if n > MAX_PSI:
        raise WristmarkError(f"the live view carries arms of up to {MAX_PSI} configuration variables, this one has {n}")
    server = MeshcatServer.start(title=title, host=host, stream=stream)
    image_path = Path(tempfile.mkdtemp(prefix="wristmark-live-")) / "left.png" if config.camera is not None else None
    try:
        worker = _start_worker(server, config, rate_hz, trail_seconds, image_path)
    except BaseException:
        server.close()
        raise
    view = LiveView(server, worker, image_path)
    if stream is not None:
        print(f"live 3D view: open {view.url}", file=stream, flush=True)
    return view


def start_scene_live_view(setup: ArmsSetup, *, title: str = "wristmark live view: several arms",
                          rate_hz: float = DEFAULT_RATE_HZ, trail_seconds: float = DEFAULT_TRAIL_SECONDS,
                          stream: TextIO | None = sys.stderr, host: str | None = None) -> SceneLiveView:
    """Start the live view of every arm of a scene (sim.scene_setup.SceneSetup): the server (its
    legend names each arm in its colour) and the drawing process; prints the URL on ``stream``.
    Loopback only unless ``host`` adds an address (viz.web_hosts)."""
    from wristmark.viz.style import arms_legend

    if not rate_hz > 0:
        raise WristmarkError(f"live view rate must be > 0 Hz, got {rate_hz}")
    if not trail_seconds >= 0:
        raise WristmarkError(f"trail length must be >= 0 s, got {trail_seconds}")
    config = ArmsSceneConfig.from_scene_setup(setup)
    for name, c in config.arms.items():
        if arm_size(c.params)[0] > MAX_PSI:
            raise WristmarkError(f"the live view carries arms of up to {MAX_PSI} configuration variables; "
                                 f"arm {name} has {arm_size(c.params)[0]}")
    server = MeshcatServer.start(title=title, host=host, stream=stream, legend=arms_legend(config.names))
    try:
        worker = _start_worker(server, config, rate_hz, trail_seconds)
    except BaseException:
        server.close()
        raise
    view = SceneLiveView(server, worker, config.names)
    if stream is not None:
        print(f"live 3D view: open {view.url}", file=stream, flush=True)
    return view
