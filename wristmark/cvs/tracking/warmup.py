"""Pay a tracker's one-time costs before the first frame that is timed.

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

import numpy as np

from wristmark.cvs.marker.synthetic import marker_pose_ahead, synthetic_pair
from wristmark.cvs.tracking.tracker import MarkerTracker


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
