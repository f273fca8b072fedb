"""The virtual lab: one process plays the actuator box and the stereo endoscope, so that a host
sees only what it would see in a lab, serial bytes and a video stream (docs/design.md "The virtual lab").

:class:`VirtualLab` drives the simulated true arm from an actuator-box emulator on a new pty
(protocol v1 or v2, wall clock) and, in a camera thread, samples that arm in wall-clock time at up to
``fps`` frames per second on a fixed frame clock (frame k starts k periods after the first, so a
host can lock its cycle to the frames' phase; where rendering cannot keep up, the next frame
starts at once and the clock restarts from it), has it rendered by a process of its own
(:mod:`sim.render.process`) and publishes each stereo pair side by side as a JPEG of an MJPEG stream on loopback
(:class:`cvs.sources.mjpeg_server.MjpegServer`). Each frame's capture instant is the emulator clock's
``time.monotonic()`` when the arm was sampled; ``truth_out`` logs it with the true tip in {w}
[m] (CSV header ``t,tip_x,tip_y,tip_z``), one row per published frame.

Each JPEG also carries its capture instant (cvs.sources.jpeg_stamp, a COM segment decoders ignore):
valid only because both processes read one machine's monotonic clock, and not something a real
camera needs (a host stamps a real camera's frames at arrival, or maps the device's own
timestamps). With it, the host's capture-to-command latency includes the frame's transport
(rendering, JPEG encoding, the loopback hop, decoding), which the host logs apart; without it
(any other MJPEG sender) the transport is hidden in a frame that looks fresh on arrival.
:attr:`VirtualLab.stats` reports what the camera side spends per frame.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.cvs.sources.mjpeg_server import MjpegServer
from wristmark.models.arm_shape import ArmShape
from wristmark.models.arm_spec import Arm, home_psi
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.rig.loop.realtime_priority import MAX_PRIORITY, check_realtime_priority, request_realtime_priority
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.dense_truth import TRUTH_HEADER, DenseTruthArm
from wristmark.sim.locked_arm import LockedArm
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.render.process import RenderedJpeg, RenderProcess

FIRST_FRAME_TIMEOUT_S = 60.0  # [s] the first render compiles nothing (numba caches) but a loaded host is slow


@dataclass(frozen=True)
class LabCamera:
    """The virtual endoscope: fps [1/s] at most; image_scale of the calibrated size; render noise
    preset and seed; JPEG quality (1-100); host and TCP port of the stream (0: any free port)."""

    fps: float = 30.0
    image_scale: float = 1.0
    noise: str = "default"
    seed: int = 0
    jpeg_quality: int = 90
    host: str = "127.0.0.1"
    port: int = 0

    def validate(self) -> None:
        """InputError naming the bad option."""
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise InputError(f"--fps must be > 0, got {self.fps}")
        if not (np.isfinite(self.image_scale) and 0 < self.image_scale <= 1):
            raise InputError(f"--image-scale must be in (0, 1], got {self.image_scale}")
        if not 1 <= self.jpeg_quality <= 100:
            raise InputError(f"JPEG quality must be in 1..100, got {self.jpeg_quality}")
        if self.host not in ("127.0.0.1", "localhost", "::1"):
            raise InputError(f"the virtual lab serves on loopback only, not {self.host!r}")


@dataclass
class CameraStats:
    """What the camera thread did: frames published, render and JPEG-encode times [ms]."""

    frames: int = 0
    render_ms: list[float] = field(default_factory=list)
    encode_ms: list[float] = field(default_factory=list)
    t_first: float = float("nan")
    t_last: float = float("nan")

    def summary(self) -> dict[str, Any]:
        """Counts, achieved rate [1/s] and median times [ms]."""
        span = self.t_last - self.t_first
        return {"frames": self.frames, "fps": (self.frames - 1) / span if self.frames > 1 and span > 0 else None,
                "render_ms_median": float(np.median(self.render_ms)) if self.render_ms else None,
                "encode_ms_median": float(np.median(self.encode_ms)) if self.encode_ms else None}


class StreamingLab:
    """What every virtual lab shares: actuator boxes on ptys (:meth:`_serve_boxes`, a subclass's)
    and one endoscope sampling them in a camera thread on the frame clock (:meth:`_frame`, a
    subclass's), rendered in a process of its own and published on an MJPEG stream on loopback;
    the truth CSV; real-time priorities as :class:`VirtualLab` describes."""

    def __init__(self, camera: LabCamera | None, truth_out: str | Path | None, rt_priority: int | None,
                 render_rt: bool) -> None:
        self.options = camera or LabCamera()
        self.options.validate()
        if rt_priority is not None:
            check_realtime_priority(min(MAX_PRIORITY, rt_priority + 1))
        self.rt_priority = rt_priority
        self.render_rt = bool(render_rt)
        self._render: RenderProcess | None = None
        self.truth_path = Path(truth_out) if truth_out else None
        self.stats = CameraStats()
        self.server: MjpegServer | None = None
        self._truth: IO[str] | None = None
        self._stop = threading.Event()
        self._frozen = threading.Event()
        self._first = threading.Event()
        self._start_error: Exception | None = None
        self._thread: threading.Thread | None = None
        self.error = ""

    @property
    def url(self) -> str:
        """The stream's URL (after :meth:`start`)."""
        return self.server.url if self.server is not None else ""

    def _start_stream(self, camera: StereoCamera, markers: MarkerModel | list[MarkerModel], header: str) -> None:
        """Open the truth file (``header``), the render process (``camera`` at the image scale,
        ``markers``), the boxes' ptys and the stream, and start the camera; returns after the
        first frame was published (else stops the lab and raises)."""
        if self.truth_path is not None:
            self.truth_path.parent.mkdir(parents=True, exist_ok=True)
            self._truth = open(self.truth_path, "w", buffering=1)
            self._truth.write(header + "\n")
        try:
            self._render = RenderProcess(camera, markers, self.options.noise, self.options.seed,
                                         self.options.jpeg_quality, self.rt_priority if self.render_rt else None)
        except BaseException:
            self.stop()
            raise
        launcher = threading.Thread(target=self._start_threads, name="virtual-lab-start")
        launcher.start()  # the lab's threads inherit the launcher's scheduling, not the caller's
        launcher.join()
        if self._start_error is not None:
            self.stop()
            raise self._start_error
        if not self._first.wait(FIRST_FRAME_TIMEOUT_S) or self.error:  # a frame from the first client on
            self.stop()
            raise InputError(self.error or "the virtual endoscope rendered no frame within "
                             f"{FIRST_FRAME_TIMEOUT_S:g} s")

    def _serve_boxes(self) -> None:
        """Open the actuator boxes' ptys (in the boxes' real-time priority)."""
        raise NotImplementedError

    def _frame(self) -> float:
        """Sample, render, publish, log the truth; returns the capture instant [s]."""
        raise NotImplementedError

    def _start_threads(self) -> None:
        try:
            if self.rt_priority is not None:  # the boxes' threads one above the rest
                request_realtime_priority(min(MAX_PRIORITY, self.rt_priority + 1))
            self._serve_boxes()
            if self.rt_priority is not None:
                request_realtime_priority(self.rt_priority)
            self.server = MjpegServer(self.options.host, self.options.port)
            self._thread = threading.Thread(target=self._run_camera, name="virtual-endoscope", daemon=True)
            self._thread.start()
        except Exception as e:  # noqa: BLE001 - handed to start(), which raises it in the caller's thread
            self._start_error = e

    def _publish(self, shapes: ArmShape | list[ArmShape]) -> RenderedJpeg:
        """Render ``shapes`` (in {w} [m]) and count the frame; the caller publishes it."""
        assert self.server is not None and self._render is not None
        out = self._render.render_jpeg(shapes)
        st = self.stats
        st.frames += 1
        st.render_ms.append(out.render_ms)
        st.encode_ms.append(out.encode_ms)
        return out

    def _log_truth(self, t: float, tips: list[np.ndarray]) -> None:
        """One truth row: the capture instant [s] and the true tips [m]."""
        st = self.stats
        st.t_first = t if st.frames == 1 else st.t_first
        st.t_last = t
        if self._truth is not None:
            row = ",".join(f"{float(v):.9g}" for tip in tips for v in tip)
            self._truth.write(f"{t:.6f},{row}\n")

    def freeze_camera(self) -> None:
        """Stop publishing frames while the stream stays open (a stalled camera; fault injection)."""
        self._frozen.set()

    def _run_camera(self) -> None:
        period = 1.0 / self.options.fps
        t_next = time.monotonic()
        while not self._stop.is_set():
            wait = t_next - time.monotonic()
            if wait > 0 and self._stop.wait(wait):
                return
            if self._frozen.is_set():
                t_next = time.monotonic() + period
                continue
            try:
                self._frame()
            except Exception as e:  # noqa: BLE001 - the camera dies with one line; the stream then stalls
                self.error = f"virtual endoscope stopped: {type(e).__name__}: {e}"
                self._first.set()
                return
            self._first.set()
            t_next = next_frame_start(t_next, period, time.monotonic())

    def _stop_boxes(self) -> None:
        """Stop the actuator boxes."""
        raise NotImplementedError

    def stop(self) -> None:
        """Stop the camera, the stream and the boxes; close the truth file (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None
        if self.server is not None:
            self.server.close()
        if self._render is not None:
            self._render.close()
            self._render = None
        self._stop_boxes()
        if self._truth is not None:
            self._truth.close()
            self._truth = None

    def __enter__(self) -> StreamingLab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


class VirtualLab(StreamingLab):
    """The actuator box on a pty and the endoscope on an MJPEG stream, around one simulated arm.

    rt_priority: run every thread of the lab (actuator box, camera, renderer, stream server)
    under ``SCHED_FIFO`` at this priority (:mod:`rig.loop.realtime_priority`), as firmware and a camera
    are not starved by the host's other work; all of them, since a normal thread holding
    Python's GIL would stall the real-time ones (priority inversion). The actuator box's thread
    runs one priority above the others. The rendering runs in a process of its own
    (:mod:`sim.render.process`: it shares no GIL with the box), in real time at ``rt_priority``
    too, or at normal priority with ``render_rt`` False: for a renderer that needs every core,
    which in real time would eat the machine's real-time budget and throttle the host's loop.
    The caller's thread keeps its own scheduling.
    emulator_factory: ``(arm, params, watchdog_s=...) -> ActuatorEmulator`` (tests record packets).
    truth_dense_out: also log the true tip every few ms of the box's clock, not only at the frames
    (:mod:`sim.dense_truth`; same CSV format as ``truth_out``).
    """

    def __init__(self, params: Arm, plant: PlantParams, calibration: StereoCamera, marker: MarkerModel,
                 camera: LabCamera | None = None, psi0: Any = None, watchdog_s: float = 0.25,
                 truth_out: str | Path | None = None, rt_priority: int | None = None, render_rt: bool = True,
                 emulator_factory: Callable[..., ActuatorEmulator] | None = None,
                 truth_dense_out: str | Path | None = None) -> None:
        super().__init__(camera, truth_out, rt_priority, render_rt)
        if calibration.T_world_left is None:
            raise InputError("the virtual lab's calibration needs 'world_T_left' (camera pose in {w})")
        if any(plant.camera_offset):  # the endoscope truly sits at world_T_left @ T(camera_offset)
            W = np.asarray(calibration.T_world_left, float) @ plant.camera_offset_transform()
            calibration = dataclasses.replace(calibration, T_world_left=W)
        cam = calibration if self.options.image_scale == 1.0 else scaled_stereo_camera(calibration,
                                                                                     self.options.image_scale)
        start = np.asarray(psi0, float) if psi0 is not None else home_psi(params)
        self._plant = TruePlant(params, plant, psi0=start)
        self._own_tip_force = np.asarray(self._plant.plant.tip_force, float)
        self.arm = self._locked = LockedArm(self._plant)
        self.dense_truth = DenseTruthArm(self.arm) if truth_dense_out else None
        if self.dense_truth is not None:
            self.arm = self.dense_truth  # the emulator advances it: the true tip logged every few ms
        factory = emulator_factory or ActuatorEmulator
        self.emulator = factory(self.arm, params, watchdog_s=watchdog_s)
        if self.dense_truth is not None and truth_dense_out:  # no thread runs yet: the two clocks pair exactly
            self.dense_truth.start(self.emulator.sample_arm()[0], truth_dense_out)
        self.camera = cam  # the endoscope as rendered (at the image scale)
        self.marker = marker
        self.pty_path = ""

    def hang(self, force: np.ndarray) -> None:
        """Hang a known tip force ``force`` [N] in {w} on the arm, on top of the plant's own
        (zeros: take it off); the way ``wristmark identify --load`` is served on the virtual lab."""
        f = self._own_tip_force + np.asarray(force, float)
        with self._locked.lock:
            own = self._plant.plant
            self._plant.plant = dataclasses.replace(own, tip_force=(float(f[0]), float(f[1]), float(f[2])))

    def start(self) -> tuple[str, str]:
        """Open the pty and the stream, start the camera; returns (pty path, stream URL). The
        first frame is published before this returns."""
        self._start_stream(self.camera, self.marker, TRUTH_HEADER)
        return self.pty_path, self.url

    def _serve_boxes(self) -> None:
        self.pty_path = self.emulator.serve_pty()

    def _frame(self) -> float:
        """Sample the arm, render, publish, log the truth; returns the capture instant [s]."""
        t, shape = self.emulator.sample_arm()
        out = self._publish(shape)
        assert self.server is not None
        self.server.publish(out.jpeg, t_capture=t)
        self._log_truth(t, [shape.tip])
        if self.dense_truth is not None:
            self.dense_truth.flush()  # the box's thread only logs in memory
        return t

    def _stop_boxes(self) -> None:
        self.emulator.stop()
        if self.dense_truth is not None:
            self.dense_truth.close()

    def __enter__(self) -> VirtualLab:
        return self


def next_frame_start(t_start: float, period: float, now: float) -> float:
    """The lab camera's frame clock [s]: the next frame starts one ``period`` after the last
    one's scheduled start ``t_start`` (a wake-up's lateness does not accumulate, so a host can
    lock its cycle to the frames' phase), or at ``now`` when the last frame took longer (the
    clock restarts from it)."""
    return max(t_start + period, now)


def read_truth_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(t (N,) [s], tip (N, 3) in {w} [m]) from a ``--truth-out`` file."""
    with open(path) as f:
        header = f.readline().strip()
        if header != TRUTH_HEADER:
            raise InputError(f"{path}: not a virtual-lab truth file (header {header!r}, expected {TRUTH_HEADER!r})")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    if data.size == 0:
        return np.zeros(0), np.zeros((0, 3))
    return data[:, 0], data[:, 1:4]


def true_tip_errors(log_csv: str | Path, truth_csv: str | Path, phase: str = "servo", at: str = "t") -> np.ndarray:
    """|true tip - desired tip| [m] of each cycle of ``phase`` in a servo run's log.csv, the true
    tip interpolated from the lab's ``--truth-out`` (or ``--truth-dense-out``) at the log's column
    ``at`` (one machine, one monotonic clock): ``t``, the cycle's nominal instant, at which its
    desired tip is defined and the in-process bench takes its truth (on the wall clock the link's
    time is ``time.monotonic()``), or ``t_wall``, when the host's cycle actually began (a few ms
    later: the truth there is compared with the desired tip of an earlier instant); NaN for
    cycles outside the truth's time span."""
    t, tip = read_truth_csv(truth_csv)
    return tip_errors(log_csv, t, tip, phase, at)


def tip_errors(log_csv: str | Path, t: np.ndarray, tip: np.ndarray, phase: str = "servo",
               at: str = "t") -> np.ndarray:
    """|true tip - desired tip| [m] of each cycle of ``phase`` in a servo run's log.csv, the true
    tip ``tip`` (N, 3) [m] in the log's {w} at times ``t`` (N,) [s] interpolated at the log's
    column ``at`` (``t`` or ``t_wall``); NaN for cycles outside the truth's time span."""
    from wristmark.rig.recording.run_log import read_log_csv

    if at not in ("t", "t_wall"):
        raise InputError(f"errors are evaluated at 't' or 't_wall', not {at!r}")
    log = read_log_csv(log_csv)
    sel = np.array([p == phase for p in log["phase"]], bool)
    t_wall = np.asarray(log[at], float)[sel]
    p_des = np.stack([np.asarray(log[f"p_des_{a}"], float)[sel] for a in "xyz"], axis=1)
    if t.size < 2:
        return np.full(len(t_wall), np.nan)
    p_true = np.stack([np.interp(t_wall, t, tip[:, i]) for i in range(3)], axis=1)
    err = np.linalg.norm(p_true - p_des, axis=1)
    err[(t_wall < t[0]) | (t_wall > t[-1])] = np.nan
    return err
