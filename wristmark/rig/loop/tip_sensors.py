"""Where the servo loop's tip measurement comes from: a stereo frame in, a tip in {w} out.

A :class:`TipSensor` gets a :class:`cvs.sources.frames.StereoFrame` (from a camera, a video, a stream,
or the simulated bench's renderer) and returns a :class:`TipMeasurement` stamped with the
frame's capture time, so the loop measures its capture-to-command latency from the frames
themselves. :class:`VisionTipSensor` runs the marker tracker on the frame's pixels; it never
sees the arm. (The simulated bench's explicit fast option, truth plus noise, lives in
:mod:`sim.truth_sensor`: only the simulated bench knows the truth.)
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.marker import MarkerModel

if TYPE_CHECKING:
    from wristmark.cvs.tracking.result import TrackResult

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TipMeasurement:
    """One tip measurement in {w} [m] from the frame captured at ``t_capture`` [s] (the frame's
    clock: the host's ``time.monotonic()`` on hardware, simulated time on the simulated bench);
    ``ok`` False with a ``reason`` when there is none. time_ms: the tracking time [ms];
    corners_left: the detected corners in the left image's raw pixels (N, 2), for a viewer;
    T_left_marker, tip_left: the marker pose (4x4 of {wm}) and the tip in {ll} [m], for a recorder;
    R_world: the tip frame's orientation in {w} (3x3; = {wm}'s) when measured, roll_known: its roll
    about z is known (a coded sleeve whose code was read), else only its z axis is meaningful (the
    reference sleeve: roll modulo one column); T_world_marker: the marker's pose {wm} in {w} (4x4
    [m]) when measured (published as ``NS/marker/measured_cp`` by ``servo --ros2``); tip_sigma_m:
    the tip's own standard deviation [m] as the tracker reports it (TrackResult.tip_sigma_m; NaN:
    not estimated)."""

    ok: bool
    p_world: Array | None
    reason: str = ""
    time_ms: float = 0.0
    rms_px: float = float("nan")
    t_capture: float = float("nan")
    frame_index: int = -1
    corners_left: Array | None = None
    T_left_marker: Array | None = None
    tip_left: Array | None = None
    R_world: Array | None = None
    roll_known: bool = False
    T_world_marker: Array | None = None
    tip_sigma_m: float = float("nan")


class TipSensor(Protocol):
    """Anything that measures the tip of the arm in {w} [m] from a stereo frame."""

    def measure(self, frame: StereoFrame, axis_hint_world: Array | None = None) -> TipMeasurement:
        """Measure the tip in ``frame``; ``axis_hint_world``: the expected direction of the
        marker's z axis in {w} (e.g. the model's at the commanded configuration)."""
        ...


class VisionTipSensor:
    """Track the marker in a stereo frame's pixels; the tip in {w} through the calibration's
    ``world_T_left`` (or a separate registration, ``T_world_left``)."""

    def __init__(self, camera: StereoCamera, marker: MarkerModel, T_world_left: Array | None = None,
                 magnify: float = 1.0) -> None:
        """``magnify``: the tracker's enlarged search of a lost pair (TrackerSettings.magnify)."""
        from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings

        self.camera = camera
        W = T_world_left if T_world_left is not None else camera.T_world_left
        self.T_world_left = None if W is None else np.asarray(W, float)
        self.tracker = MarkerTracker(camera, marker, TrackerSettings(magnify=magnify))
        self.last_frame: StereoFrame | None = None

    def measure(self, frame: StereoFrame, axis_hint_world: Array | None = None) -> TipMeasurement:
        """Track the frame; the time reported is the tracking time only [ms]. The axis hint picks
        which way the marker points (its pattern is symmetric under a half turn)."""
        self.last_frame = frame
        hint = None
        if axis_hint_world is not None and self.T_world_left is not None:
            hint = self.T_world_left[:3, :3].T @ np.asarray(axis_hint_world, float)
        t0 = time.perf_counter()
        res = self.tracker.track(frame.left, frame.right, axis_hint_left=hint)
        return tip_measurement(res, frame, 1000.0 * (time.perf_counter() - t0), self.T_world_left)


def tip_measurement(res: TrackResult, frame: StereoFrame, ms: float, T_world_left: Array | None) -> TipMeasurement:
    """A tracking result in {ll} as the loop's measurement in {w} through ``T_world_left`` (pose of
    {ll} in {w}, 4x4 [m]; None: no measurement); ``ms``: the tracking time [ms]."""
    corners = np.asarray(res.corners_left, float).reshape(-1, 2)
    if not res.ok or res.tip_left is None or T_world_left is None:
        reason = res.reason or ("marker not found" if res.tip_left is None else "no world_T_left")
        return TipMeasurement(False, None, reason, ms, t_capture=frame.t_capture,
                              frame_index=frame.index, corners_left=corners)
    W = T_world_left
    p = (np.asarray(res.tip_left, float).reshape(1, 3) @ W[:3, :3].T + W[:3, 3])[0]
    T = None if res.T_left_marker is None else np.asarray(res.T_left_marker, float)
    return TipMeasurement(True, p, "", ms, float(res.rms_px), frame.t_capture, frame.index, corners, T,
                          np.asarray(res.tip_left, float), None if T is None else W[:3, :3] @ T[:3, :3],
                          bool(res.roll_known), None if T is None else W @ T, float(res.tip_sigma_m))


class DeadlineTipSensor:
    """Another sensor's measurement, given up after ``budget`` [s] so that a cycle never outlasts
    the actuator box's watchdog.

    The tracker usually takes milliseconds, but a frame that needs a search of the whole image
    (the marker far from where the last frame had it, e.g. from a slow camera) took 368 ms once
    on the loaded 2-core machine at 1080p, and the box's 250 ms watchdog then stopped the run. The
    measurement runs in a worker thread (the tracker releases the GIL in OpenCV and numba); the
    caller waits at most ``budget``, then gets a failed measurement (the loop holds the arm for
    that cycle, as for a lost marker) while the worker finishes, so the tracker still learns
    where the marker is for the next frame. A frame that comes while the worker is still busy
    is not measured (failed too)."""

    def __init__(self, inner: TipSensor, budget: float) -> None:
        from concurrent.futures import ThreadPoolExecutor

        if not budget > 0:
            raise ValueError(f"budget must be > 0 s, got {budget}")
        self.inner = inner
        self.budget = float(budget)
        self.late = 0  # measurements given up
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="tip-sensor")
        self._busy: object = None

    def measure(self, frame: StereoFrame, axis_hint_world: Array | None = None) -> TipMeasurement:
        """The inner sensor's measurement, or a failed one when it takes longer than the budget
        or the previous one is still running."""
        from concurrent.futures import Future, TimeoutError

        t0 = time.perf_counter()
        busy = self._busy
        if isinstance(busy, Future) and not busy.done():
            return TipMeasurement(False, None, "tracker still busy with an earlier frame", 0.0,
                                  t_capture=frame.t_capture, frame_index=frame.index)
        job = self._pool.submit(self.inner.measure, frame, axis_hint_world)
        self._busy = job
        try:
            return job.result(timeout=self.budget)
        except TimeoutError:
            self.late += 1
            ms = 1000.0 * (time.perf_counter() - t0)
            return TipMeasurement(False, None, f"tracking took longer than {1000 * self.budget:.0f} ms", ms,
                                  t_capture=frame.t_capture, frame_index=frame.index)

    def close(self) -> None:
        """Let a running measurement finish and stop the worker."""
        self._pool.shutdown(wait=True)
