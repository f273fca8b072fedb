"""One arm's :class:`MarkerTracker` in a worker process of its own: :class:`RemoteTracker`.

``ArmSetTracker(..., processes=True)`` (cvs.tracking.arm_set) tracks every arm but the first
in a worker process, so that the arms' ROI searches run on two cores at once: a ROI search is
mostly Python holding the interpreter lock, so threads of one process overlap little
(docs/notes/several-arms.md "Time").

- **The state lives in the worker.** The worker builds the arm's real :class:`MarkerTracker`
  (its detectors' boxes, the last pose, the start-pose bookkeeping) from the same camera, marker,
  settings and family; every call that reads or changes that state is sent to it, in order, over
  a pipe: ``track``, ``reset``, ``adopt`` and ``refit`` (a refit's start poses include the
  previous pose). ``reset`` and ``adopt`` need no answer and are not waited for (an error in
  them is raised by the next call that waits). ``tracking`` is mirrored here from the answers
  (a track's result says it; reset clears it, adopt sets it). ``contrast_gate`` and ``settings``
  read no state (the settings, the camera and the marker's points): they run here, on a twin
  tracker built from the same arguments, so that no image crosses for them. A phase-one track
  may also ask the worker to gate its result once it has sent it (``gate_after``): the arm set
  clears and gates its own arm meanwhile, and takes the worker's gate where clearing left that
  result as it was (a function of the result and the pair only: the same bits).
- **Frames cross through shared memory.** One :class:`SharedFrames` buffer per arm set
  (``multiprocessing.shared_memory``, two views of up to 4 channels at the calibrated size) holds
  the pair a worker tracks: the parent copies the pair into it (~0.5 ms for two 1080p BGR views),
  sends each worker the views' shapes, tracks its own arm meanwhile and then receives each
  worker's result (pickled: corners, pose, match, code; floats keep every bit). The parent
  writes the buffer only while no worker reads it (every answer owed is received first).
- **Only with a core to spare.** With another process busy on one of two cores, the parent and
  its worker share the other, and the copy and the messages (~1 ms a pair) come on top: slower
  than threads (docs/notes/several-arms.md "Time"). So it is opt-in.
- **Lifetime.** Workers start with ``spawn`` (the parent has threads and numba's; ``fork``
  would copy their locks; the worker imports the parent's main script, which therefore needs
  the ``if __name__ == "__main__":`` guard), once per arm set: the worker imports the tracker,
  loads numba's kernels (``warm_up``, with the parent's number of OpenCV threads) and says it is
  ready (~2 s on the 2-core machine; the constructor waits, ``start_timeout_s``). ``reset`` keeps
  the workers. :meth:`RemoteTracker.close` stops a worker (asked, then terminated, then
  killed); a finalizer does it when the proxy is collected or at the interpreter's exit, the
  workers are daemons, and a worker whose parent is gone (its pipe closed, or the parent
  process replaced) ends itself: no orphan.
- **Failures.** A worker that ends (killed, crashed) or does not answer within
  ``timeout_s`` raises :class:`ArmWorkerError` (one line, the arm and the exit code) instead of
  hanging; the worker is then stopped and every later call raises the same error (the arm set
  cannot go on without that arm's state: build another). An exception inside the worker's
  tracker is raised in the parent as it was raised there.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Sequence
from multiprocessing import get_context
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.tracking.result import Array, TrackResult
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.errors import InputError, WristmarkError
from wristmark.models.marker import MarkerModel

__all__ = ["ArmWorkerError", "PendingTrack", "RemoteTracker", "SharedFrames", "start_remote_trackers"]

Shape = tuple[int, ...]
START_TIMEOUT_S = 120.0  # spawn, imports and numba's kernels (compiled on the first run after an install: ~30 s)
CALL_TIMEOUT_S = 30.0  # one pair (a whole-frame search of a loaded machine takes well under 1 s)


class ArmWorkerError(WristmarkError, RuntimeError):
    """An arm's worker process ended or stopped answering (the arm set cannot go on: build another)."""


class SharedFrames:
    """A shared-memory buffer for one stereo pair of uint8 views (h, w) or (h, w, c), c <= 4, of
    the calibrated size: the parent writes it (:meth:`put`), the workers read it (:meth:`views`)."""

    def __init__(self, image_size: tuple[int, int], name: str | None = None) -> None:
        w, h = int(image_size[0]), int(image_size[1])
        self.capacity = h * w * 4  # bytes per view
        self.shm = SharedMemory(name=name, create=name is None, size=2 * self.capacity if name is None else 0)
        self.name = self.shm.name
        self.readers: list[RemoteTracker] = []  # put() waits for their owed answers first
        # the creator frees it when closed, collected or at the interpreter's exit
        self._finalizer = weakref.finalize(self, _release, self.shm, name is None)

    def put(self, left: NDArray[np.uint8], right: NDArray[np.uint8]) -> tuple[Shape, Shape]:
        """Copy a pair into the buffer once no worker reads it (every answer owed received); the
        views' shapes (for :meth:`views`)."""
        for r in self.readers:
            r.settle()
        for k, img in enumerate((left, right)):
            if img.dtype != np.uint8 or img.nbytes > self.capacity:
                raise InputError(f"a view of {img.dtype} {img.shape} does not fit the shared frame buffer")
            np.copyto(self._view(k, img.shape), img)
        return tuple(left.shape), tuple(right.shape)

    def views(self, shapes: tuple[Shape, Shape]) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """The pair last put, as arrays over the buffer (valid until the next :meth:`put`)."""
        return self._view(0, shapes[0]), self._view(1, shapes[1])

    def _view(self, k: int, shape: Shape) -> NDArray[np.uint8]:
        return np.ndarray(shape, np.uint8, buffer=self.shm.buf, offset=k * self.capacity)

    def close(self) -> None:
        """Detach (every array of :meth:`views` must be gone); its creator frees it. Idempotent."""
        self._finalizer()


def _release(shm: SharedMemory, unlink: bool) -> None:
    try:
        shm.close()
    except BufferError:  # an array over it still lives: the memory goes with the process
        pass
    if unlink:
        try:
            shm.unlink()
        except FileNotFoundError:
            pass


class PendingTrack:
    """A track sent to a worker, its answers not yet received: :meth:`result` waits for the
    result, :meth:`gated` for the worker's contrast gate of it (asked with ``gate_after``)."""

    def __init__(self, remote: RemoteTracker) -> None:
        self.remote = remote
        self.value: TrackResult | None = None
        self.gate: tuple[TrackResult | None] | None = None  # (the gated result, or None: not ok)

    def result(self) -> TrackResult:
        """The track's result (the worker's answers are received in the order of the calls)."""
        while self.value is None:
            self.remote._receive_next()
        return self.value

    def gated(self) -> TrackResult:
        """MarkerTracker.contrast_gate of :meth:`result`, computed in the worker (``gate_after``)."""
        res = self.result()
        while self.gate is None:
            self.remote._receive_next()
        return res if self.gate[0] is None else self.gate[0]


class RemoteTracker:
    """Arm ``arm``'s :class:`MarkerTracker` in a worker process, with the interface the arm set
    uses (``track``, ``reset``, ``adopt``, ``refit``, ``contrast_gate``, ``tracking``,
    ``settings``, ``marker``, ``camera``): the same results, to the bit, as that tracker in
    this process. Build with :func:`start_remote_trackers`."""

    def __init__(self, arm: str, camera: StereoCamera, marker: MarkerModel, settings: TrackerSettings | None,
                 family: Sequence[MarkerModel], frames: SharedFrames, timeout_s: float = CALL_TIMEOUT_S) -> None:
        import cv2

        self.arm, self.frames, self.timeout_s = arm, frames, float(timeout_s)
        self._twin = MarkerTracker(camera, marker, settings, family=family)  # stateless calls, here
        self.settings, self.marker, self.camera = self._twin.settings, marker, camera
        self._tracking = False
        self._owed: list[tuple[PendingTrack, str]] = []  # answers not yet received, in order: 'track' or 'gate'
        self._ready = False
        self._broken: ArmWorkerError | None = None
        ctx = get_context("spawn")
        self._conn, child = ctx.Pipe()
        self.process: BaseProcess = ctx.Process(
            target=_serve, name=f"wristmark-arm-{arm}", daemon=True,
            args=(child, frames.name, camera, marker, self.settings, list(family), cv2.getNumThreads(), os.getpid()))
        self.process.start()
        child.close()  # the worker's end: ours closed, so its death reads as the pipe's end
        self._finalizer = weakref.finalize(self, _stop, self.process, self._conn)
        frames.readers.append(self)

    # -- the MarkerTracker interface ------------------------------------------------------------

    @property
    def tracking(self) -> bool:
        """The worker's tracker is in ROI tracking (mirrored from its answers)."""
        return self._tracking

    def track(self, left_img: Any, right_img: Any, axis_hint_left: Array | None = None,
              roi_only: bool = False, contrast_gate: bool = True) -> TrackResult:
        """MarkerTracker.track in the worker: the pair copied into the shared buffer, then tracked."""
        shapes = self.frames.put(np.asarray(left_img), np.asarray(right_img))
        return self.submit(shapes, axis_hint_left, roi_only, contrast_gate).result()

    def submit(self, shapes: tuple[Shape, Shape], axis_hint_left: Array | None = None, roi_only: bool = False,
               contrast_gate: bool = True, gate_after: tuple[float | None, float | None] | None = None) -> PendingTrack:
        """Start MarkerTracker.track in the worker on the pair already in the shared buffer
        (``shapes``: :meth:`SharedFrames.put`'s; :meth:`SharedFrames.put` waits for every answer
        owed first). ``gate_after``: (contrast_noise, max_sigma_m) of a :meth:`contrast_gate` the
        worker applies to the result once it has sent it (``gated()``), while this process goes on."""
        self._send("track", (shapes, axis_hint_left, bool(roi_only), bool(contrast_gate), gate_after))
        pending = PendingTrack(self)
        self._owed.append((pending, "track"))
        if gate_after is not None:
            self._owed.append((pending, "gate"))
        return pending

    def settle(self) -> None:
        """Receive every answer still owed (a caller that raised between a submit and its result,
        or a gate not asked for), so that the next call's answer is its own and the shared buffer
        is free."""
        while self._owed:
            self._receive_next()

    def reset(self) -> None:
        """MarkerTracker.reset in the worker (not waited for)."""
        self._send("reset", None)
        self._tracking = False

    def adopt(self, res: TrackResult) -> None:
        """MarkerTracker.adopt in the worker (not waited for; the same check first, here)."""
        if not res.ok or res.pose is None:
            raise InputError("only a good result can be adopted")
        self._send("adopt", res)
        self._tracking = True

    def refit(self, res: TrackResult, keep_left: NDArray[np.bool_], keep_right: NDArray[np.bool_],
              max_sigma_ratio: float = float("inf")) -> TrackResult | None:
        """MarkerTracker.refit in the worker (its start poses read the tracker's previous pose)."""
        self._send("refit", (res, keep_left, keep_right, max_sigma_ratio))
        out = self._receive()
        return None if out is None else _result(out)

    def contrast_gate(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                      contrast_noise: float | None = None, max_sigma_m: float | None = None) -> TrackResult:
        """MarkerTracker.contrast_gate, here (it reads no tracker state)."""
        return self._twin.contrast_gate(res, views, contrast_noise, max_sigma_m)

    # -- the process ------------------------------------------------------------------------------

    def wait_ready(self, timeout_s: float = START_TIMEOUT_S) -> None:
        """Wait until the worker has loaded its kernels and built its tracker."""
        if not self._ready:
            msg = self._wait(timeout_s, "start")
            if msg[0] == "error":
                self._fail(f"arm '{self.arm}': its worker process failed to start: {msg[1]}")
            self._ready = True

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the worker (asked; terminated or killed after ``timeout_s``). Idempotent."""
        self._owed = []
        if self._finalizer.alive:
            self._finalizer.detach()
            _stop(self.process, self._conn, timeout_s)
        if self._broken is None:
            self._broken = ArmWorkerError(f"arm '{self.arm}': its worker process was closed")

    def _send(self, op: str, payload: Any) -> None:
        if self._broken is not None:
            raise self._broken
        self.settle()
        try:
            self._conn.send((op, payload))
        except (BrokenPipeError, ConnectionError, OSError):
            self._fail(self._ended())

    def _receive_next(self) -> None:
        """The oldest owed answer, into its :class:`PendingTrack` (a track's also the mirrored ``tracking``)."""
        pending, kind = self._owed.pop(0)
        if kind == "gate":
            gated = self._receive()
            pending.gate = (None if gated is None else _result(gated),)
            return
        try:
            res, tracking = self._receive()
        except Exception:
            if self._owed and self._owed[0] == (pending, "gate"):
                self._owed.pop(0)  # a track that raised in the worker is not gated there
            raise
        self._tracking = bool(tracking)
        pending.value = _result(res)

    def _receive(self) -> Any:
        """The worker's next answer (an exception raised in the worker is raised here)."""
        self.wait_ready()
        msg = self._wait(self.timeout_s, "answer")
        if msg[0] == "error":
            raise msg[1]
        return msg[1]

    def _wait(self, timeout_s: float, what: str) -> tuple[str, Any]:
        if self._broken is not None:
            raise self._broken
        ready = wait([self._conn, self.process.sentinel], timeout_s)
        if self._conn in ready:
            try:
                msg: tuple[str, Any] = self._conn.recv()
                return msg
            except (EOFError, OSError):
                pass
        elif not ready:
            self._fail(f"arm '{self.arm}': its worker process did not {what} within {timeout_s:g} s (killed); "
                       "build the arm set again")
        self._fail(self._ended())
        raise AssertionError  # not reached

    def _ended(self) -> str:
        self.process.join(1.0)
        code = self.process.exitcode
        how = f"exit code {code}" if code is None or code >= 0 else f"killed by signal {-code}"
        return f"arm '{self.arm}': its worker process ended ({how}); build the arm set again"

    def _fail(self, message: str) -> None:
        """Stop the worker at once (it is dead or stuck: no polite stop) and raise ``message``."""
        self._broken = ArmWorkerError(message)
        self._owed = []
        if self._finalizer.alive:
            self._finalizer.detach()
            if self.process.is_alive():
                self.process.kill()
                self.process.join(1.0)
            self._conn.close()
        raise self._broken


def _result(res: Any) -> TrackResult:
    if not isinstance(res, TrackResult):
        raise ArmWorkerError(f"an arm's worker process answered {type(res).__name__}, not a TrackResult")
    return res


def _stop(process: BaseProcess, conn: Connection, timeout_s: float = 5.0) -> None:
    """Ask a worker to stop, then terminate it, then kill it; close the pipe."""
    try:
        if process.is_alive():
            try:
                conn.send(("stop", None))
            except (BrokenPipeError, ConnectionError, OSError):
                pass
            process.join(timeout_s)
            if process.is_alive():
                process.terminate()
                process.join(1.0)
            if process.is_alive():
                process.kill()
                process.join(1.0)
    finally:
        conn.close()


def start_remote_trackers(camera: StereoCamera, markers: Sequence[MarkerModel], settings: TrackerSettings | None,
                          family: Sequence[MarkerModel], timeout_s: float = CALL_TIMEOUT_S,
                          start_timeout_s: float = START_TIMEOUT_S) -> tuple[SharedFrames, list[RemoteTracker]]:
    """One worker per marker (started together, ready when this returns) and the frame buffer
    they share (freed with the last of them: a finalizer, or at the interpreter's exit)."""
    frames = SharedFrames(camera.image_size)
    remotes: list[RemoteTracker] = []
    try:
        for m in markers:
            remotes.append(RemoteTracker(str(m.arm), camera, m, settings, family, frames, timeout_s))
        for r in remotes:
            r.wait_ready(start_timeout_s)
    except BaseException:
        for r in remotes:
            r.close(1.0)
        frames.close()
        raise
    return frames, remotes


def _serve(conn: Connection, shm_name: str, camera: StereoCamera, marker: MarkerModel, settings: TrackerSettings,
           family: list[MarkerModel], cv_threads: int, parent_pid: int) -> None:
    """The worker: build the tracker, say ready, then answer the parent's calls in order until
    it says stop, its pipe ends or it is gone."""
    try:
        from wristmark.cvs.tracking.warmup import warm_up

        warm_up(opencv_threads=max(1, cv_threads))
        tracker = MarkerTracker(camera, marker, settings, family=family)
        frames = SharedFrames(camera.image_size, name=shm_name)
    except BaseException as e:  # the parent raises it, one line
        conn.send(("error", f"{type(e).__name__}: {e}"))
        return
    conn.send(("ready", None))
    deferred: BaseException | None = None  # an error of a call that is not waited for
    while True:
        if not conn.poll(1.0):
            if os.getppid() != parent_pid:
                break  # the parent is gone
            continue
        try:
            op, payload = conn.recv()
        except (EOFError, OSError):
            break
        if op == "stop":
            break
        try:
            if op == "reset":
                tracker.reset()
            elif op == "adopt":
                tracker.adopt(payload)
            elif deferred is not None:
                err, deferred = deferred, None
                raise err
            elif op == "track":
                shapes, hint, roi_only, gate, after = payload
                il, ir = frames.views(shapes)
                res = tracker.track(il, ir, axis_hint_left=hint, roi_only=roi_only, contrast_gate=gate)
                conn.send(("ok", (res, tracker.tracking)))
                if after is not None:  # the parent goes on meanwhile; the same bits as its own gate
                    op = "gate"
                    conn.send(("ok", tracker.contrast_gate(res, (il, ir), *after) if res.ok else None))
                del il, ir
            elif op == "refit":
                conn.send(("ok", tracker.refit(*payload)))
            else:
                raise ArmWorkerError(f"unknown call '{op}' to an arm's worker process")
        except Exception as e:  # noqa: BLE001 - sent to the parent, raised there
            if op in ("reset", "adopt"):
                deferred = e
            else:
                conn.send(("error", _picklable(e)))
    frames.close()


def _picklable(e: BaseException) -> BaseException:
    """``e`` if it survives pickling, else an ArmWorkerError with its type and message."""
    import pickle

    try:
        pickle.loads(pickle.dumps(e))
        return e
    except Exception:  # noqa: BLE001
        return ArmWorkerError(f"{type(e).__name__}: {e}")
