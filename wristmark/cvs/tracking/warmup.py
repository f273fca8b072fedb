"""Pay one-time costs before the first frame that is timed: the process's (:func:`warm_up`) and
a tracker's (:func:`warm_up_tracker`).

Building a tracker, a detector or a renderer changes nothing process-wide; :func:`warm_up` is
the one explicit call that does (every command of the CLI, bench and example that times frames
calls it first): OpenCV's worker threads (one by default: on this project's 2-core machine one
thread was faster for every filter the tracker and the renderer run) and numba's kernels,
loaded from the disk cache (compiled on the first run after an install, ~12-30 s) by tracking
small synthetic pairs of the packaged camera, once per process.

The first use of each code path of ``MarkerTracker.track`` costs far more than later ones:
numba loads (or compiles) a kernel for each new argument type on its first call, the corner
detector's reusable buffers are allocated (and page-faulted) at the whole frame's size by the
first whole-frame search, CasADi and OpenCV set up on their first calls, and the 'auto'
detector builds its saddle fallback only when a pair is first lost. Measured in one process on
this machine: the first coded-sleeve read 1.1 s (the code decoder's kernels), the first BGR
direction check 1.2 s, the first whole-frame pair 38 ms of CPU against 21 ms for the same
pair with a second tracker. Paced at 60 fps (16.7 ms a frame) each of those drops frames.

:func:`warm_up_tracker` runs every path once on synthetic frames of the calibration's size
(cvs.marker.synthetic: real pixels of the sleeve, code patches included), then forgets the
state: a cold pair (whole-frame search, every start pose, the direction and the code), the same
pair in ROI tracking, the pair with an axis hint, and an empty pair (the ROIs miss, the second
detector tries the same boxes, the whole frames are searched and the second detector runs).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from wristmark.models.errors import InputError

if TYPE_CHECKING:  # imported where used: warm_up(jit=False) imports OpenCV only
    from wristmark.cvs.tracking.tracker import MarkerTracker

_JIT_READY: list[bool] = []  # warm_up's kernels are loaded in this process


@dataclass(frozen=True)
class WarmUp:
    """What a warm-up ran: seconds taken [s], pairs tracked [-] and how many found the marker [-]."""

    seconds: float
    pairs: int
    found: int


def warm_up_tracker(tracker: MarkerTracker, channels: Sequence[int] = (1,)) -> WarmUp:
    """Track synthetic pairs through every code path of ``tracker`` for each image kind in
    ``channels`` (1: grey views, 3: BGR), then reset its ROI state; its results are unchanged
    by this (only one-time costs are paid)."""
    import numpy as np

    from wristmark.cvs.marker.synthetic import marker_pose_ahead, synthetic_pair

    t0 = time.perf_counter()
    pairs = found = 0
    hint = marker_pose_ahead(tracker.marker, tracker.camera)[:3, 2]  # z_wm in {ll}
    for ch in channels:
        left, right = synthetic_pair(tracker.camera, tracker.marker, ch)
        blank = np.full_like(left, 90)
        tracker.reset()
        for images, axis_hint in (((left, right), None), ((left, right), None), ((left, right), hint),
                                  ((blank, blank), None)):
            res = tracker.track(*images, axis_hint_left=axis_hint)
            pairs += 1
            found += int(res.ok)
    tracker.reset()
    return WarmUp(time.perf_counter() - t0, pairs, found)


def warm_up(opencv_threads: int | None = 1, jit: bool = True) -> float:
    """Prepare this process for timed tracking and rendering (the only wristmark call that changes
    process-wide state): ``opencv_threads`` sets OpenCV's worker threads for the whole process
    (``cv2.setNumThreads``; None leaves them), ``jit`` loads (or, first time, compiles) every
    numba kernel the marker tracker runs, for grey and BGR views and both sleeves (once per
    process; later calls skip it). Returns the time taken [s]."""
    t0 = time.perf_counter()
    if opencv_threads is not None:
        if isinstance(opencv_threads, bool) or not isinstance(opencv_threads, int) or opencv_threads < 1:
            raise InputError(f"opencv_threads must be a whole number >= 1 or None, got {opencv_threads!r}")
        import cv2

        cv2.setNumThreads(opencv_threads)
    if jit and not _JIT_READY:
        from wristmark.cvs.calibration.load import load_calibration
        from wristmark.cvs.camera import scaled_stereo_camera
        from wristmark.cvs.corners.detector import run_kernels_once
        from wristmark.cvs.tracking.foreshortening import run_kernels_once as run_foreshortening_kernel
        from wristmark.cvs.tracking.print_edges import run_kernels_once as run_edge_kernels
        from wristmark.cvs.tracking.tracker import MarkerTracker
        from wristmark.models.config_files import CONFIG_DIR
        from wristmark.models.marker import MarkerModel

        run_kernels_once()  # the detector's, including the planar board's detect_xcorners
        run_edge_kernels()  # the print bars' search (not reached at the warm-up's quarter size)
        run_foreshortening_kernel()  # a corner's patch drawn at the fit (corners facing the camera obliquely)
        # a quarter-size camera: the kernels' types do not depend on the image size
        camera = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.25)
        for marker in (MarkerModel(), MarkerModel.load(CONFIG_DIR / "marker_coded.yaml")):
            warm_up_tracker(MarkerTracker(camera, marker), (1, 3))
        _JIT_READY.append(True)
    return time.perf_counter() - t0
