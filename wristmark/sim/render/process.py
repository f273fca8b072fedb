"""The virtual endoscope's renderer in a process of its own: arm shapes in, JPEG frames out.

Rendering a 1080p stereo pair keeps both cores busy for 70-400 ms on this project's machine.
In the process of the actuator box it shared Python's GIL with the box's thread: whenever the
rendering thread held the GIL and the scheduler preempted it (other work, or a real-time host),
the box could not answer (measured: "no valid reply after 3 attempts of 50 ms" and watchdog trips
in 1080p virtual-lab runs at load 11-14, even with the box's thread in real time). In a process
of its own the renderer shares nothing with the box: it may run at normal priority, slowly,
and the box and the stream still answer at once.

:class:`RenderProcess` starts the process (``spawn``: no threads inherited) with the camera,
marker, noise preset and seed; :meth:`RenderProcess.render_jpeg` sends one :class:`ArmShape`
and returns the side-by-side pair (left | right, rendered into one image: no copy)
JPEG-encoded, with the render and encode times (:func:`render_pair_jpeg` is that pipeline).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.arm_shape import ArmShape
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

if TYPE_CHECKING:  # the renderer (numba, OpenCV) is imported in the render process only
    from wristmark.sim.render.stereo_renderer import StereoRenderer

U8 = NDArray[np.uint8]
START_TIMEOUT_S = 120.0  # [s] the process imports numba, OpenCV and the scene on a loaded host


@dataclass(frozen=True)
class RenderedJpeg:
    """One frame: the side-by-side JPEG [bytes] and what it cost in the render process [ms]."""

    jpeg: bytes
    render_ms: float
    encode_ms: float


def encode_jpeg(image: U8, quality: int) -> bytes:
    """JPEG bytes of a uint8 image (BGR or grey) at ``quality`` (1-100)."""
    import cv2

    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise InputError("JPEG encoding failed")
    return bytes(buf.tobytes())


def render_pair_jpeg(renderer: StereoRenderer, shape: ArmShape, quality: int) -> tuple[bytes, U8, U8]:
    """What the render process does per frame: render ``shape`` (in {w} [m]) into one
    side-by-side image (left | right, no copy) and JPEG-encode it at ``quality`` (1-100).
    Returns (the JPEG, the left image, the right image), the images views of that one buffer."""
    both, pair = renderer.render_side_by_side(shape)
    return encode_jpeg(both, quality), pair.left, pair.right


def _serve(conn: Connection, camera: StereoCamera, marker: MarkerModel | list[MarkerModel], noise: str, seed: int,
           quality: int, rt_priority: int | None) -> None:
    """The render process: a shape (or a list of them, one per marker: several arms in one view)
    in, a RenderedJpeg (or an error line) out, until None or EOF."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the lab's to handle, not ours
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        from wristmark.cvs.tracking.warmup import warm_up
        from wristmark.sim.render.settings import noise_preset
        from wristmark.sim.render.stereo_renderer import StereoRenderer

        warm_up(jit=False)  # this process's OpenCV threads: one (the renderer's kernels load on its first frame)
        renderer = StereoRenderer(camera, marker, noise_preset(noise), seed=seed)
        if rt_priority is not None:  # after the renderer's own (right-view) thread started: it
            from wristmark.rig.loop.realtime_priority import request_realtime_priority

            request_realtime_priority(rt_priority)  # stays normal, so one core is never real time
        conn.send("ready")
    except Exception as e:  # noqa: BLE001 - one line for the lab
        conn.send(f"error: {type(e).__name__}: {e}")
        return
    while True:
        try:
            shape = conn.recv()
        except (EOFError, OSError):
            return
        if shape is None:
            return
        try:
            r0 = time.perf_counter()
            if isinstance(shape, list):  # several arms, hiding one another where they cross
                both, _ = renderer.render_arms_side_by_side(shape)
            else:
                both, _ = renderer.render_side_by_side(shape)
            r1 = time.perf_counter()
            jpeg = encode_jpeg(both, quality)
            out: Any = RenderedJpeg(jpeg, 1e3 * (r1 - r0), 1e3 * (time.perf_counter() - r1))
        except Exception as e:  # noqa: BLE001 - one line for the lab
            out = f"error: {type(e).__name__}: {e}"
        try:
            conn.send(out)
        except (BrokenPipeError, OSError):
            return


class RenderProcess:
    """The renderer of the virtual endoscope, running in its own process (see the module docstring).

    rt_priority: run that process's main thread (the left view, JPEG encoding) under SCHED_FIFO
    at this priority (None: normal priority); the renderer's right-view thread stays at normal
    priority, so the rendering never holds both cores in real time (measured with both in real
    time: the real-time budget ran out and the host's loop skipped 15 cycles of a 20 s cube)."""

    def __init__(self, camera: StereoCamera, marker: MarkerModel | Sequence[MarkerModel], noise: str = "default",
                 seed: int = 0, quality: int = 90, rt_priority: int | None = None) -> None:
        ctx = mp.get_context("spawn")
        self._conn, child = ctx.Pipe()
        markers = marker if isinstance(marker, MarkerModel) else list(marker)
        self._proc = ctx.Process(target=_serve, args=(child, camera, markers, noise, seed, int(quality), rt_priority),
                                 name="virtual-endoscope-renderer", daemon=True)
        self._proc.start()
        child.close()
        if not self._conn.poll(START_TIMEOUT_S):
            self.close()
            raise InputError(f"the virtual endoscope's renderer did not start within {START_TIMEOUT_S:g} s")
        msg = self._recv()
        if msg != "ready":
            self.close()
            raise InputError(f"the virtual endoscope's renderer did not start: {msg}")

    @property
    def pid(self) -> int | None:
        """The render process's id."""
        return self._proc.pid

    def _recv(self) -> Any:
        try:
            return self._conn.recv()
        except (EOFError, OSError):
            return "error: the render process ended"

    def render_jpeg(self, shape: ArmShape | Sequence[ArmShape]) -> RenderedJpeg:
        """Render ``shape`` (in {w} [m]; or one shape per marker, several arms) and JPEG-encode the
        pair side by side; InputError with the render process's one line when it failed or ended."""
        try:
            self._conn.send(shape if isinstance(shape, ArmShape) else list(shape))
        except (BrokenPipeError, OSError):
            raise InputError("the virtual endoscope's render process ended") from None
        out = self._recv()
        if isinstance(out, str):
            raise InputError(f"the virtual endoscope's renderer failed: {out.removeprefix('error: ')}")
        assert isinstance(out, RenderedJpeg)
        return out

    def close(self) -> None:
        """Stop the process (idempotent)."""
        if self._proc.is_alive():
            try:
                self._conn.send(None)
            except (BrokenPipeError, OSError):
                pass
            self._proc.join(5.0)
            if self._proc.is_alive():
                self._proc.terminate()
                self._proc.join(2.0)
        self._conn.close()
