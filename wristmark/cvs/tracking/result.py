"""One stereo pair's tracking result (cvs.tracking.tracker.MarkerTracker.track)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.marker.decode import CodeReading
from wristmark.cvs.tracking.stereo_match import StereoMatch
from wristmark.cvs.tracking.stereo_pose import MarkerPose

Array = NDArray[np.float64]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class TrackResult:
    """One stereo pair's tracking result (left camera frame {ll}, metres).

    ok: a pose was found and passed the checks; reason: why not ('' when ok); tip_left, tip_world
    [m] (tip_world None without world_T_left); T_left_marker: 4x4 pose of {wm} in {ll};
    corners_left/right: detected corners in raw pixels (N, 2); rms_px [px]; time_ms: total [ms];
    timings: ms per stage (detect, match, init, solve); pose: the solver result when one ran;
    axis_source: what fixed the direction of z_wm ('hint', 'previous', 'image', 'default' or
    'code' or 'none'; '' when not ok); axis_score: the image evidence in [-1, 1] for the
    returned direction (NaN when the image was not asked); roll_known: a coded sleeve's code
    was read, T_left_marker is the absolute pose (roll included) and ids_left / ids_right the
    absolute corner ids of corners_left / right (-1: not used); otherwise roll is known modulo
    one column and ids are None; code: the code reading (coded sleeves); corner_sigmas: the
    noise [px] of each matched corner (left, right: as corners_*[match.index_* >= 0]) that
    weighted the pose solve (TrackerSettings.solve_contrast_noise), None when unweighted;
    tip_sigma_m: the tip's standard deviation [m] (the larger of the sleeve's two ends, along its
    worst direction) at the used corners' contrast noise and residuals, the print's bars
    included where they were weighed in: what the contrast gate judged
    (MarkerTracker.contrast_tip_sigma), and where the eroded search fitted the corners again with
    their clipped pixels censored, each corner beside a clipped pixel clipped_sigma_px noisier;
    the reduced search's, every corner at TrackerSettings.reduced_sigma_px (its corners' measured
    noise) times the fit's residual over it where that is the larger (on the held-out path-traced
    sets no tracked tip was more than 2.61 of it off, docs/notes/highlight-stripe.md); under
    TrackerSettings.gate_min_spacing_px of spacing, for a fit on chains that step over a missed
    corner, and for one arm's other fits there (the small-fit gate, max_small_fit_tip_sigma_m),
    every corner at corner_sigma_px times the fit's residual over it; NaN where not estimated
    (several arms' other fits under that spacing, where the contrast relation overstates the
    noise, or the contrast gate off).
    """

    ok: bool
    reason: str
    tip_left: Array | None
    tip_world: Array | None
    T_left_marker: Array | None
    corners_left: Array
    corners_right: Array
    rms_px: float
    time_ms: float
    timings: dict[str, float]
    pose: MarkerPose | None = None
    match: StereoMatch | None = None
    axis_source: str = ""
    axis_score: float = float("nan")
    roll_known: bool = False
    ids_left: IntArray | None = None
    ids_right: IntArray | None = None
    code: CodeReading | None = None
    corner_sigmas: tuple[Array, Array] | None = None
    tip_sigma_m: float = float("nan")
