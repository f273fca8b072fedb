"""The stereo tracking pipeline of paper Sec. III: corners -> correspondence -> pose -> tip.

``MarkerTracker.track(left_img, right_img)`` runs, per stereo pair: the corner detector in each
image (ROI tracking from pair to pair, whole frame when lost), rectified-y correspondence with
relative indices (cvs.tracking.stereo_match), the homography start (eq. 14-15, or triangulation
+ Kabsch when a camera sees fewer than 4 corners or the homography start does not converge),
the CasADi stereo solve (eq. 16) and the tip (eq. 5). It returns ``ok=False`` with a reason
rather than a doubtful pose: no marker, too few corners, no stereo pairs, a residual above
``max_rms_px``, a tip the corners barely determine (its standard deviation at
``corner_sigma_px`` of corner noise above ``max_tip_sigma_m``: cvs.tracking.tip_uncertainty), a
fit that puts a corner on the far side of the sleeve (few corners: the arc
turned inside out, cvs.tracking.sleeve_facing; a start in the other minimum is tried first), or
a fit that hinges on corners seen in one view only (the best fit of the stereo pairs alone puts
the tip more than ``max_single_view_shift_m`` away). With the 'auto' detector a pair the paper
detector loses is tried with the saddle detector, whose coarser corners are then fitted again by
the paper detector's model at the fit's own edge directions (cvs.tracking.corner_refit: a
highlight can bend one corner's edge out of the paper's chain). A pair lost for too few corners gets one
last try with chains that step over a missed corner (a specular highlight over the corner the
camera sees best: cvs.corners.detector ``retry_with_gaps``, docs/notes/highlight-stripe.md). A
pair whose corners fit no pose (RMS above ``max_rms_px``) gets one more with one end corner of
a view's chain left out (an X-like corner at the sleeve's silhouette that extends a chain). A
pair still lost for too few corners, where both views saw the marker before, has each view's
box around its last good corners searched enlarged (``TrackerSettings.magnify``: a small or
steeply seen sleeve's squares a few pixels wide; docs/notes/steep-views.md). A pair then still
lost, one of whose fits hinged on corners seen in one view only, has those corners looked for in
the other view (:meth:`MarkerTracker._retry_partners`); one still lost for want of corners is
searched in each whole view reduced 2-4 times (corners blurred over several pixels:
:meth:`MarkerTracker._retry_reduced`), then, where both views clip, eroded
(:meth:`MarkerTracker._retry_eroded`); the corners these two find are fitted again on the views
themselves. Last, a good,
oriented result is refused when its tip's standard deviation at its corners' contrast noise,
scaled up by the fit's residual where that exceeds the noise, is above
``max_contrast_tip_sigma_m`` (:meth:`MarkerTracker.contrast_gate`: a dark sleeve's dim corners,
or corners that fit worse than their contrast says; the corners' ROIs are kept).
``track_corners`` takes corners directly (controller loops, baselines, tests).

The sleeve looks the same after a half turn about x_wm, so which way z_wm (distal) points is
decided after the solve, and never guessed: a coded sleeve's code (cvs.marker.decode: the
absolute pose, roll included, ``roll_known``); else a caller's ``axis_hint_left`` (e.g. the
kinematic model's marker axis in a servo loop); else the previous pair's pose, but only when
this fit is consistent with it (chains found in the previous ROIs, small motion: within
``prior_max_move_m``, ``prior_max_turn_deg`` and ``prior_max_px``) and the image
(cvs.tracking.axis) does not contradict it; else decisive image evidence (the arm's body
continues behind the sleeve, nothing lies beyond the tip) that the same evidence at the arm's
width alone backs (``AxisEvidenceSettings.arm_offsets``, by ``decide``; unbacked, it counts as
marginal: a glossy tool's lit shaft and open jaws scored 0.36 the wrong way on a path-traced
pair whose arm bent away from the far band), and last the default prior
``PoseSettings.axis_hint_left`` (+x: the arm enters from the left). Marginal image evidence
(``AxisEvidenceSettings.margin`` above ``decide``) decides only where the default prior agrees;
where they disagree the result is ``ok=False``, "direction ambiguous" (a lit tool beside the
sleeve gave a path-traced pair 0.145 the wrong way: docs/notes/highlight-stripe.md), unless the
same evidence at the arm's width alone (``AxisEvidenceSettings.arm_offsets``: a thin tool and its
shadow ring left out) decisively backs the prior, which then decides. With
``TrackerSettings.strict_direction`` the image evidence must hold in both of its bands
(cvs.tracking.axis.axis_evidence_strict) and there is no default: otherwise the result is
``ok=False`` with reason "direction ambiguous" (never a guess; a distal tool as wide as the arm
with no body behind the sleeve fools the lenient evidence). ``TrackResult.axis_source`` says which one
decided.
"""

from __future__ import annotations

import inspect
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.corners.subpixel import HTM_WEIGHT_MAX_PX, HTM_WEIGHT_PER_SPACING, chain_spacing
from wristmark.cvs.gray_image import check_view, to_gray
from wristmark.cvs.marker.decode import CodeDecoder
from wristmark.cvs.tracking.axis import axis_evidence, axis_evidence_strict
from wristmark.cvs.tracking.corner_refit import (
    corner_edge_angles,
    nearest_spacing,
    partner_corners,
    refit_corners,
    refit_corners_clipped,
)
from wristmark.cvs.tracking.epipolar_box import epipolar_box
from wristmark.cvs.tracking.foreshortening import htm_bias
from wristmark.cvs.tracking.homography_init import homography_pose
from wristmark.cvs.tracking.print_edges import (
    Bars,
    Corners,
    PrintedEdges,
    bar_pairs,
    edges_tip_sigma,
    measure_edges,
    print_is_negative,
    printed_edges,
    refine_with_edges,
)
from wristmark.cvs.tracking.result import Array, IntArray, TrackResult
from wristmark.cvs.tracking.rigid_fit import chord_starts, kabsch, roll_about_z
from wristmark.cvs.tracking.settings import CornerDetector, TrackerSettings, make_detector
from wristmark.cvs.tracking.sleeve_facing import corner_facing, turned_start
from wristmark.cvs.tracking.stereo_match import StereoMatch, StereoRectifier, match_corners
from wristmark.cvs.tracking.stereo_pose import MarkerPose, StereoPoseSolver
from wristmark.cvs.tracking.tip_uncertainty import corner_sigmas, near_clipped, tip_sigma
from wristmark.cvs.tracking.two_pairs import RollFit, StereoChord, axis_from_edges, roll_hypotheses, stereo_chords
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

# failures for too few corners (track_corners' words): a chain broken by a highlight
_CORNER_REASONS = ("no marker found", "too few marker corners", "only ")
# ... and those of a fit on few corners: more corners from an enlarged search may settle them
_FEW_CORNER_REASONS = (*_CORNER_REASONS, "the fit puts marker corners", "the fit hinges", "the tip is uncertain")
# ... and those after which the views are searched eroded, where they clip (MarkerTracker._retry_eroded)
_ERODED_REASONS = (*_CORNER_REASONS, "no start pose")
# ... and those after which the whole views are searched reduced (MarkerTracker._retry_reduced)
_REDUCED_REASONS = (*_FEW_CORNER_REASONS, "no start pose")
# how the tip-sigma gate's refusal ends, after which the print's bars are weighed in (_retry_with_bars)
_TIP_SIGMA_CAUSE = "to fix the marker's tilt)"
_CONTRAST_GATE_CAUSE = "at the corners' contrast noise and residuals"  # contrast_gate's refusal
_SMALL_FIT_CAUSE = "at a small marker's corner noise and residuals"  # contrast_gate's, under gate_min_spacing_px
# the timings keys of a result whose corners were fitted again with their clipped pixels censored
# (MarkerTracker._retry_reduced, _retry_eroded): its reported sigma counts its clipped corners noisier
_CLIPPED_REFITS = ("reduced_refit", "eroded_refit")
# the timings key of a result fitted on chains that step over a missed corner (MarkerTracker._retry_with_gaps,
# _retry_other_view): under gate_min_spacing_px the contrast gate judges it at corner_sigma_px
_GAP_FIT = "gap_chain_fit"
_TWO_PAIRS_MAX_CHORDS = 4  # stereo chords of two corners judged (MarkerTracker._retry_two_pairs), at most


def _median(x: Array) -> float:
    """np.median of a 1-D array to the bit (its middle value, or the mean of its two middle
    values: (a + b) / 2, as np.mean of two), without its Python machinery (~15 us a call)."""
    if x.size == 0 or not np.isfinite(x).all():
        return float(np.median(x))
    s = np.sort(x)
    m = s.size // 2
    return float(s[m]) if s.size % 2 else float((s[m - 1] + s[m]) / 2.0)


def _median_spacing(*chains: Array) -> float:
    """The median distance [px] between consecutive corners of the chains (inf without any)."""
    gaps = [np.hypot(*np.diff(c, axis=0).T) for c in chains if c.shape[0] > 1]
    return _median(np.concatenate(gaps)) if gaps else float("inf")


def _box_around(corners: Array, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """The box (x, y, w, h) [px] around a view's corners with room for two more corners at each
    end and the marker's rows beside them (margin: twice the largest spacing, at least 8 px)."""
    gaps = np.hypot(*np.diff(corners, axis=0).T) if corners.shape[0] > 1 else np.zeros(1)
    margin = max(2.0 * float(gaps.max()), 8.0)
    h, w = int(shape[0]), int(shape[1])
    lo = np.maximum(np.floor(corners.min(axis=0) - margin), 0).astype(int)
    hi = np.minimum(np.ceil(corners.max(axis=0) + margin), [w - 1, h - 1]).astype(int)
    return int(lo[0]), int(lo[1]), int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)

__all__ = ["CornerDetector", "MarkerTracker", "TrackResult", "TrackerSettings", "kabsch"]


class MarkerTracker:
    """Stereo tip tracker for one calibration and marker; keeps ROI state between pairs. Poses in
    {ll} [m]; the tip also in {w} when the calibration has ``world_T_left``."""

    def __init__(self, camera: StereoCamera, marker: MarkerModel, settings: TrackerSettings | None = None,
                 family: Sequence[MarkerModel] = ()) -> None:
        """``family``: the coded sleeves in use (a marker set of ``marker``'s layout); the code then
        decides which of them this sleeve is (``res.code.arm``; cvs.marker.decode)."""
        self.settings = settings or TrackerSettings()
        camera.validate()
        marker.validate()
        self.camera, self.marker = camera, marker
        self.rectifier = StereoRectifier(camera)
        self.solver = StereoPoseSolver(camera, marker, self.settings.pose)
        self.detector_left = make_detector(self.settings.detector, self.settings.paper_detector)
        self.detector_right = make_detector(self.settings.detector, self.settings.paper_detector)
        T_rl = np.eye(4)
        T_rl[:3, :3], T_rl[:3, 3] = camera.R, camera.T
        self._T_left_right = np.linalg.inv(T_rl)
        self._tracking = False
        self._continuous = False  # this pair's chains were found in the previous pair's ROIs
        self._last_pose: MarkerPose | None = None  # the previous pair's good pose
        self._last_fit_px = float("inf")  # RMS of the previous pose's corners on this pair's [px]
        self._last_shift = 0  # even index shift from the previous pair's fit to this pair's (tracking)
        self._last_oriented = False  # the previous pose's direction was decided
        self.decoder = None if marker.code is None else CodeDecoder(camera, marker, self.settings.code, family)
        self._second: tuple[CornerDetector, CornerDetector] | None = None
        self._print_edges: PrintedEdges | None = None  # the print's bar samples (print_edges), on first use
        self._misfits: list[tuple[Array, Array, Array | None, Array | None]] = []  # this pair's
        # this pair's fits refused as hinging on single-view corners (_retry_partners)
        self._hinged: list[tuple[Array, Array, Array, Array, MarkerPose, StereoMatch]] = []
        self._gap_chains: tuple[Any, Any] | None = None  # this pair's chains (CornerChain), from _retry_with_gaps
        self._reduced_last_resort: TrackResult | None = None  # this pair's reduced fit for the end (_last_resort)
        self._gate_residual = float("nan")  # the last contrast gate's residual factor (_wide_if_surer)
        self._views: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None = None  # the pair track() is on
        self._use_second = self.settings.detector == "auto" and type(self.detector_left).__name__ != (
            "SaddleCornerDetector")
        # each view's corners of the last good pair [px] (a lost pair's enlarged search looks there)
        self._seen: tuple[Array | None, Array | None] = (None, None)
        self._eroded_size = 0  # the erosion [px] of the last pair _retry_eroded tracked (tried first)
        self._roi_magnify = 1.0  # the ROI search's enlargement (the last pair was found enlarged)
        self._magnifies = all("magnify" in inspect.signature(d.detect).parameters
                              for d in (self.detector_left, self.detector_right))

    def _fail(self, reason: str, cl: Array, cr: Array, t0: float, timings: dict[str, float], **kw: Any) -> TrackResult:
        return TrackResult(
            False, reason, None, None, None, cl, cr, float("nan"), 1e3 * (time.perf_counter() - t0), timings, **kw
        )

    def track(self, left_img: Any, right_img: Any, axis_hint_left: Array | None = None,
              roi_only: bool = False, contrast_gate: bool = True) -> TrackResult:
        """Track the marker in one stereo pair (grayscale or BGR uint8 images of the calibrated
        size). In ROI tracking only the boxes around the previous corners are converted to grey
        and searched; whole frames are converted once, when a whole-frame search is needed.
        ``axis_hint_left``: expected direction of z_wm (distal) in {ll}, if the caller knows it.
        ``roi_only``: search only the boxes of ROI tracking, never the whole frames (``ok=False``
        when they lose the marker, or when there are none: cvs.tracking.arm_set searches the whole
        frames itself, with the other arms' sleeves painted out). ``contrast_gate``: the result
        passes :meth:`contrast_gate` (False: the caller applies it, as cvs.tracking.arm_set does
        after clearing each arm's corners)."""
        t0 = time.perf_counter()
        self._continuous = False
        self._misfits = []
        self._hinged = []
        self._gap_chains = None
        self._reduced_last_resort = None
        il = check_view(left_img, self.camera.image_size, "left")
        ir = check_view(right_img, self.camera.image_size, "right")
        self._views = (il, ir)  # the tip-sigma gate looks at each used corner here
        try:
            res = self._track_views(il, ir, t0, axis_hint_left, roi_only, contrast_gate)
        finally:
            self._views = None
        # the whole call, every search and retry included (a lost pair's result comes from its last one)
        return replace(res, time_ms=1e3 * (time.perf_counter() - t0))

    def _track_views(self, il: NDArray[np.uint8], ir: NDArray[np.uint8], t0: float, axis_hint_left: Array | None,
                     roi_only: bool, gate: bool = True) -> TrackResult:
        """``track``'s work on the checked views."""
        if roi_only and not self._tracking:
            return self._fail("no ROI to search (roi_only)", np.zeros((0, 2)), np.zeros((0, 2)), t0, {})
        res, full = self._track_in_rois(il, ir, t0, whole=not roi_only) if self._tracking else (None, (None, None))
        if roi_only and res is None:
            return self._fail("no ROI to search (roi_only)", np.zeros((0, 2)), np.zeros((0, 2)), t0, {})
        if res is None or (not res.ok and not roi_only):
            # cold, or the ROIs lost the marker: the whole frames (a side already searched whole
            # in this pair is not searched again: the search is a function of the image)
            t1 = time.perf_counter()
            t_roi = 0.0 if res is None else res.timings.get("detect", 0.0)
            if res is None or not any(c is not None and len(c.corners) < self.settings.min_corners for c in full):
                il, ir = to_gray(il), to_gray(ir)
                dl = full[0] if full[0] is not None else self.detector_left.detect(il)
                dr = full[1] if full[1] is not None else self.detector_right.detect(ir)
                res = self.track_corners(dl.corners, dr.corners, dl.polarity, dr.polarity, _t0=t0)
            res.timings["detect"] = t_roi + 1e3 * (time.perf_counter() - t1)
        if not res.ok and self._use_second and not roi_only:
            # 'auto': one try with the other detector (different failure modes, same pose gates)
            t2 = time.perf_counter()
            il, ir = to_gray(il), to_gray(ir)
            second = self._second_detectors()
            sl, sr = second[0].detect(il), second[1].detect(ir)
            t_second = 1e3 * (time.perf_counter() - t2)
            res2 = self.track_corners(sl.corners, sr.corners, sl.polarity, sr.polarity, _t0=t0)
            if res2.ok:
                res = self._first_detector_in_boxes(res2, il, ir, t0, (sl.polarity, sr.polarity))
            res.timings["second_detector"] = t_second
        if not res.ok and res.reason.startswith(_CORNER_REASONS):
            res = self._retry_with_gaps(res, t0)
        if not res.ok and self._misfits:
            res = self._retry_without_chain_ends(res, t0)
        magnified = False
        if not res.ok and res.reason.startswith(_FEW_CORNER_REASONS):
            res, magnified = self._retry_magnified(res, il, ir, t0)
        if not res.ok and not roi_only and self._hinged and self.settings.partner_max_px > 0:
            res = self._retry_partners(res, (to_gray(il), to_gray(ir)), t0)
        if not res.ok and not roi_only and res.reason.startswith(_REDUCED_REASONS):
            res = self._retry_reduced(res, il, ir, t0)
        if not res.ok and not roi_only and res.reason.startswith(_ERODED_REASONS):
            res = self._retry_eroded(res, il, ir, t0)
        if not res.ok and not roi_only:
            res = self._retry_other_view(res, (il, ir), t0)
        found = res.ok
        if found and self.settings.magnify > 1.0:  # only the enlarged search uses them
            self._seen = (res.corners_left.copy(), res.corners_right.copy())
            spacing = _median_spacing(res.corners_left, res.corners_right)
            self._roi_magnify = self.settings.magnify if magnified and spacing < self.settings.magnify_below_px else 1.0
        if res.ok:
            res = self._judged(res, (il, ir), axis_hint_left, gate)
            if not res.ok and not roi_only and _CONTRAST_GATE_CAUSE in res.reason:
                res = self._retry_wide_windows(res, (il, ir), t0, axis_hint_left)
            elif res.ok and not roi_only and self._gate_residual > self.settings.wide_residual_factor > 0:
                res = self._wide_if_surer(res, (il, ir), t0, axis_hint_left)
            res = replace(res, time_ms=1e3 * (time.perf_counter() - t0))
        elif gate and not roi_only and res.reason.endswith(_TIP_SIGMA_CAUSE):
            res = self._retry_with_bars(res, (to_gray(il), to_gray(ir)), t0, axis_hint_left)
            found = res.ok
        if not res.ok and gate and not roi_only and self.decoder is not None and res.reason.startswith(
                _ERODED_REASONS):
            res = self._retry_two_pairs(res, (to_gray(il), to_gray(ir)), t0)
            found = found or res.ok
        if not res.ok and self._reduced_last_resort is not None:
            res = self._last_resort(res, (il, ir), axis_hint_left, gate)
            found = found or res.pose is not None
        self._tracking = found  # an ambiguous direction keeps the corners' ROIs
        self._last_pose = res.pose if found else None
        self._last_oriented = res.ok
        return res

    def refit(self, res: TrackResult, keep_left: NDArray[np.bool_], keep_right: NDArray[np.bool_],
              max_sigma_ratio: float = float("inf")) -> TrackResult | None:
        """A good coded result solved again without some of its corners (``keep_*``: per corner of
        ``res.corners_left`` / ``right``; cvs.tracking.arm_set leaves out those another arm's
        edges reach): the same pose gates, the code's absolute frame kept (the corners left out are
        ``ids`` -1). None when the result has no code's frame, too few corners stay, or a gate
        fails, or when the corners left fix the tip more than ``max_sigma_ratio`` times worse than
        all of them (cvs.tracking.tip_uncertainty). The tracker's state (ROIs, previous pose) is
        not changed."""
        code, m, s = res.code, res.match, self.settings
        if not (res.ok and res.roll_known and code is not None and code.T_fit_abs is not None and m is not None):
            return None
        kl, kr = (m.index_left >= 0) & keep_left, (m.index_right >= 0) & keep_right
        pairs = m.pairs[kl[m.pairs[:, 0]] & kr[m.pairs[:, 1]]]
        if min(int(kl.sum()), int(kr.sum())) < s.min_corners or pairs.shape[0] < s.min_pairs:
            return None
        idx_l, ul = m.index_left[kl], res.corners_left[kl]
        idx_r, ur = m.index_right[kr], res.corners_right[kr]
        assert res.pose is not None
        sig = None if res.corner_sigmas is None else (  # the result's own weights, of the corners kept
            res.corner_sigmas[0][keep_left[m.index_left >= 0]], res.corner_sigmas[1][keep_right[m.index_right >= 0]])
        pose = self.solver.solve(idx_l, ul, idx_r, ur, res.pose.T_fit, sig)
        kept = (self._last_shift, self._last_fit_px)
        sub = replace(m, index_left=np.where(kl, m.index_left, -1), index_right=np.where(kr, m.index_right, -1),
                      pairs=pairs)
        used_l, used_r = m.index_left >= 0, m.index_right >= 0
        sigma = self._tip_sigma(pose, idx_l, idx_r)
        bad = (not pose.rms_px <= s.max_rms_px or not self._faces_cameras(pose, idx_l, idx_r)
               or sigma > s.max_tip_sigma_m
               or sigma > max_sigma_ratio * self._tip_sigma(res.pose, m.index_left[used_l], m.index_right[used_r])
               or self._single_view_shift(pose, idx_l, ul, idx_r, ur, sub) > s.max_single_view_shift_m)
        self._last_shift, self._last_fit_px = kept
        if bad:
            return None
        T = pose.T_fit @ code.T_fit_abs
        tip_left, tip_world = self.solver._tips(T)
        pose = replace(pose, T_left_marker=T, tip_left=tip_left, tip_world=tip_world)
        n = self.marker.columns
        return replace(res, tip_left=tip_left, tip_world=tip_world, T_left_marker=T, pose=pose, rms_px=pose.rms_px,
                       match=sub, ids_left=code.absolute_ids(sub.index_left, n),
                       ids_right=code.absolute_ids(sub.index_right, n), tip_sigma_m=math.nan)  # not this fit's

    def _contrast_weighted(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                           debias: bool = False) -> TrackResult:
        """A good, oriented result solved once more from its own fit with each corner weighted by
        its noise (``corner_sigma_px`` combined with ``solve_contrast_noise`` over its contrast,
        cvs.tracking.tip_uncertainty.corner_sigmas): dim corners count less. The direction, the
        roll and every gate are those of the unweighted fit (the weights move it by a fraction
        of its noise, but a marginal direction score must not flip with them); the weighted fit
        replaces it only where it keeps the same corners and reprojects within ``max_rms_px``.
        ``debias``: in the same solve, the corners less the HTM fit's bias drawn at the unweighted
        fit (:meth:`_debiased_corners`; one solve instead of two, the bias moving by far less than
        its own size between the two fits), which replace the result's corners; where that fit is
        refused, the weighted fit of the corners as found."""
        m, pose, s = res.match, res.pose, self.settings
        if m is None or pose is None or res.T_left_marker is None:
            return res
        kl, kr = m.index_left >= 0, m.index_right >= 0
        ul, ur = res.corners_left[kl], res.corners_right[kr]
        t = time.perf_counter()
        sig = (corner_sigmas(views[0], ul, s.corner_sigma_px, s.solve_contrast_noise),
               corner_sigmas(views[1], ur, s.corner_sigma_px, s.solve_contrast_noise))
        fixed = self._debiased_corners(res) if debias else None
        drawn = res.timings.get("foreshortening", 0.0) if fixed is not None else 0.0
        out = res
        if fixed is not None:
            w = self.solver.solve(m.index_left[kl], fixed[0][kl], m.index_right[kr], fixed[1][kr], pose.T_fit, sig)
            out = self._solved_again(res, w, corner_sigmas=sig, corners_left=fixed[0], corners_right=fixed[1])
        if out is res:
            w = self.solver.solve(m.index_left[kl], ul, m.index_right[kr], ur, pose.T_fit, sig)
            out = self._solved_again(res, w, corner_sigmas=sig)
        res.timings["weighted"] = 1e3 * (time.perf_counter() - t) - drawn  # the drawing has its own key
        return out

    def _solved_again(self, res: TrackResult, w: MarkerPose, **changes: Any) -> TrackResult:
        """``res`` (a good, oriented result) with the fit ``w`` of its own corners solved again,
        and ``changes`` to its other fields, where ``w`` keeps the same corners and reprojects
        within ``max_rms_px``; else ``res``. The direction and roll stay the result's."""
        pose = res.pose
        assert pose is not None and res.T_left_marker is not None
        same = (np.array_equal(w.inliers_left, pose.inliers_left)
                and np.array_equal(w.inliers_right, pose.inliers_right))
        if not (same and w.rms_px <= self.settings.max_rms_px):
            return res
        T = w.T_fit @ np.linalg.inv(pose.T_fit) @ res.T_left_marker  # the same direction and roll
        tip_left, tip_world = self.solver._tips(T)
        pose = replace(w, T_left_marker=T, tip_left=tip_left, tip_world=tip_world)
        return replace(res, pose=pose, T_left_marker=T, tip_left=tip_left, tip_world=tip_world, rms_px=w.rms_px,
                       **changes)

    def _foreshortening_debiased(self, res: TrackResult) -> TrackResult:
        """A good, oriented result solved again (with its own corner weights) from its used corners
        less the HTM fit's bias where the sleeve turns away from the camera that saw them
        (cvs.tracking.foreshortening: corners facing it at a cosine of at most
        ``foreshortening_max_facing``, drawn at the result's fit with ``foreshortening_blur_px``
        of blur; not where the chains' median spacing is under ``foreshortening_min_spacing_px``).
        The direction, the roll and every gate are the result's (as in :meth:`_contrast_weighted`);
        the new fit and its debiased corners replace the result's where it keeps the same corners
        and reprojects within ``max_rms_px``."""
        m, pose = res.match, res.pose
        if m is None or pose is None or res.T_left_marker is None:
            return res
        t = time.perf_counter()
        corners = self._debiased_corners(res)
        if corners is None:
            return res
        kl, kr = m.index_left >= 0, m.index_right >= 0
        w = self.solver.solve(m.index_left[kl], corners[0][kl], m.index_right[kr], corners[1][kr], pose.T_fit,
                              res.corner_sigmas)
        res.timings["foreshortening"] = 1e3 * (time.perf_counter() - t)
        return self._solved_again(res, w, corners_left=corners[0], corners_right=corners[1])

    def _debiased_corners(self, res: TrackResult) -> tuple[Array, Array] | None:
        """The result's corners (left, right; every corner found, the unmatched as they are) less
        the HTM fit's bias drawn at its fit (cvs.tracking.foreshortening, ``foreshortening_*``
        settings; timings key 'foreshortening'); None where no corner moves or the chains' median
        spacing is under ``foreshortening_min_spacing_px``."""
        m, pose, s = res.match, res.pose, self.settings
        assert m is not None and pose is not None
        if _median_spacing(res.corners_left, res.corners_right) < s.foreshortening_min_spacing_px:
            return None
        t = time.perf_counter()
        T_left = pose.T_fit
        T_right = np.eye(4)
        T_right[:3, :3], T_right[:3, 3] = self.camera.R, np.asarray(self.camera.T, float).reshape(3)
        corners, moved = [], False
        for camera, T, index, uv in ((self.camera.left, T_left, m.index_left, res.corners_left),
                                     (self.camera.right, T_right @ T_left, m.index_right, res.corners_right)):
            k = index >= 0
            P = self.solver.marker_points(index[k])
            facing = corner_facing(T, P, np.zeros(3))
            spacing = chain_spacing(uv)[k]  # the detector's windows: its chain's order (ends narrower)
            bias = htm_bias(camera, T, P, spacing, self.marker.radius, self.marker.beta, facing,
                            s.foreshortening_max_facing, s.foreshortening_blur_px, s.paper_detector.refine_radius,
                            window_sigmas=s.paper_detector.refine_window_sigmas)
            fixed = np.asarray(uv, float).copy()
            fixed[k] -= bias
            corners.append(fixed)
            moved = moved or bool(np.any(bias))
        res.timings["foreshortening"] = 1e3 * (time.perf_counter() - t)
        return (corners[0], corners[1]) if moved else None

    def contrast_tip_sigma(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                           contrast_noise: float | None = None) -> float:
        """The tip's standard deviation [m] of a result's fit (the larger of the sleeve's two ends)
        at each used corner's contrast noise, ``corner_sigma_px`` combined with ``contrast_noise``
        (default ``settings.gate_contrast_noise``) over its contrast in ``views``
        (cvs.tracking.tip_uncertainty.corner_sigmas), multiplied by the fit's residual over that
        noise where the residual is the larger: sqrt(chi^2 / (2 N - 6)) over the N used corners'
        pixel residuals, at least 1. Where the chains' median spacing is under
        ``settings.gate_min_spacing_px`` (the contrast relation overstates the noise there), only
        for a fit on chains that step over a missed corner (:meth:`_retry_with_gaps`,
        :meth:`_retry_other_view`: a guess of the corners' indices across the gap), and with every
        corner at ``corner_sigma_px``: such a fit whose corners do not fit the marker (held-out
        path-traced 2525/33: 21 px apart, 0.61 px, 0.53 mm off) has a residual 6 times that noise,
        where those of the fast renderer's gap fits under 23 px (0.35-0.5 x 1080p, glossy, default
        and strong noise) gave 0.16-0.32 mm of sigma. 0 where the gate does not apply: no fit, no
        contrast noise, or corners under that spacing not fitted on such chains."""
        got = self._contrast_sigmas(res, views, contrast_noise)
        return 0.0 if got is None else self._sigma_at(res, got)

    def _sigma_at(self, res: TrackResult, got: tuple[IntArray, IntArray, tuple[Array, Array], float]) -> float:
        """The tip's standard deviation [m] of ``res``'s fit at the corner noise ``got``
        (:meth:`_contrast_sigmas`)."""
        idx_l, idx_r, sig, factor = got
        assert res.pose is not None
        tip = np.asarray(self.marker.tip(), float)
        P = self.solver.marker_points
        return factor * tip_sigma(self.camera, res.pose.T_fit, P(idx_l), P(idx_r), np.stack([tip, -tip]),
                                  self.settings.corner_sigma_px, sig)

    def _contrast_sigmas(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                         contrast_noise: float | None, clipped: bool = False, small: bool = False,
                         noise_px: float | None = None
                         ) -> tuple[IntArray, IntArray, tuple[Array, Array], float] | None:
        """:meth:`contrast_tip_sigma`'s corner noise: the used corners' model indices of each
        view, their contrast noise [px] and the fit's residual factor; None where the gate does
        not apply. ``clipped``: each corner with a pixel of ``clipped_level`` or more within
        ``clipped_radius`` times the chains' spacing is ``clipped_sigma_px`` noisier, as in the
        tip-sigma gate; None where no corner is. Under ``gate_min_spacing_px`` only fits on gap
        chains are judged, unless ``small`` (:meth:`_small_fit_sigma`): every corner at
        ``corner_sigma_px``, the fit's residual factor judging. ``noise_px``: every corner at this
        noise [px] instead (the reduced search's, :meth:`_reported_sigma`), at any spacing."""
        m, pose, s = res.match, res.pose, self.settings
        noise = s.gate_contrast_noise if contrast_noise is None else float(contrast_noise)
        if m is None or pose is None or noise <= 0:
            return None
        spacing = _median_spacing(res.corners_left, res.corners_right)
        floor = spacing < s.gate_min_spacing_px  # too close together for the contrast relation
        if floor and not small and _GAP_FIT not in res.timings and noise_px is None:
            return None
        kl, kr = m.index_left >= 0, m.index_right >= 0
        in_l, in_r = np.asarray(pose.inliers_left, bool), np.asarray(pose.inliers_right, bool)
        idx_l, idx_r = m.index_left[kl][in_l], m.index_right[kr][in_r]
        ul, ur = res.corners_left[kl][in_l], res.corners_right[kr][in_r]
        own = res.corner_sigmas  # the weighted solve's, of every matched corner, at solve_contrast_noise
        if noise_px is not None:  # a search whose corners were measured at one noise
            sig = (np.full(ul.shape[0], float(noise_px)), np.full(ur.shape[0], float(noise_px)))
        elif floor:  # chains stepping over a missed corner, or a small fit: each corner at corner_sigma_px,
            # the residual judges
            sig = (np.full(ul.shape[0], s.corner_sigma_px), np.full(ur.shape[0], s.corner_sigma_px))
        elif (own is not None and noise == s.solve_contrast_noise
                and (own[0].size, own[1].size) == (in_l.size, in_r.size)):
            sig = (own[0][in_l], own[1][in_r])
        else:
            sig = (corner_sigmas(views[0], ul, s.corner_sigma_px, noise),
                   corner_sigmas(views[1], ur, s.corner_sigma_px, noise))
        if clipped and s.clipped_sigma_px > 0 and noise_px is None:
            near = [near_clipped(view, uv, s.clipped_radius * spacing, s.clipped_level) if len(uv) else
                    np.zeros(0, bool) for view, uv in zip(views, (ul, ur))]
            if not (near[0].any() or near[1].any()):
                return None  # no corner near a clipped pixel: the noise without it
            sig = (np.sqrt(sig[0]**2 + np.where(near[0], s.clipped_sigma_px**2, 0.0)),
                   np.sqrt(sig[1]**2 + np.where(near[1], s.clipped_sigma_px**2, 0.0)))
        P, T = self.solver.marker_points, pose.T_fit
        chi2 = 0.0
        for project, idx, uv, sg in ((self.camera.project_left, idx_l, ul, sig[0]),
                                     (self.camera.project_right, idx_r, ur, sig[1])):
            if idx.size:
                e = np.asarray(project(P(idx) @ T[:3, :3].T + T[:3, 3]), float).reshape(-1, 2) - uv
                chi2 += float(((e / sg[:, None]) ** 2).sum())
        dof = 2 * (idx_l.size + idx_r.size) - 6
        factor = max(1.0, float(np.sqrt(chi2 / dof))) if dof > 0 else 1.0
        return idx_l, idx_r, sig, factor

    def _small_fit_sigma(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]]) -> float:
        """The tip's standard deviation [m] of a fit whose corners are under
        ``gate_min_spacing_px`` apart (and not on gap chains, which the contrast gate judges so
        already): every corner at ``corner_sigma_px`` times the fit's residual factor; 0 where
        there is no fit. A small marker's good fits stay under 1 mm; a wrong one (three corners
        of a 9 px chain taken along the wrong line, 17 mm off) reprojects 4-7 times worse."""
        got = self._contrast_sigmas(res, views, None, small=True)
        return 0.0 if got is None else self._sigma_at(res, got)

    def _reported_sigma(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                        contrast_noise: float | None, sigma: float) -> float:
        """The ``tip_sigma_m`` a result reports: its contrast gate's ``sigma`` [m]; where the
        eroded search fitted the corners again with their clipped pixels censored, with each used
        corner near a clipped pixel ``clipped_sigma_px`` noisier (:meth:`_contrast_sigmas`,
        ``clipped``), as its own gate counts them; where the reduced search found them, with every
        corner at ``settings.reduced_sigma_px`` (their measured noise, beside clipped pixels or
        not; 0: as the eroded search's), times the fit's residual over it where that is the
        larger. Elsewhere a clipped white beside a corner does not move it (0.13 px RMS against
        0.15 px for the others on path-traced pairs), and is not counted."""
        if not any(k in res.timings for k in _CLIPPED_REFITS):
            return sigma
        if "reduced_refit" in res.timings and self.settings.reduced_sigma_px > 0:
            got = self._contrast_sigmas(res, views, contrast_noise, noise_px=self.settings.reduced_sigma_px)
        else:
            got = self._contrast_sigmas(res, views, contrast_noise, clipped=True)
        return sigma if got is None else self._sigma_at(res, got)

    def contrast_gate(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                      contrast_noise: float | None = None, max_sigma_m: float | None = None,
                      small_fits: bool = False) -> TrackResult:
        """``res`` when it is not ok or its :meth:`contrast_tip_sigma` is at most ``max_sigma_m``
        (default ``settings.max_contrast_tip_sigma_m``); else the same result ok false, without
        its tip and pose (``pose`` and ``match`` kept), the reason saying by how much the tip is
        uncertain (docs/notes/highlight-stripe.md, docs/notes/several-arms.md). With
        ``small_fits`` (one arm's tracking), a fit whose corners are too close together for that
        gate is held to ``settings.max_small_fit_tip_sigma_m`` instead (:meth:`_small_fit_sigma`,
        docs/notes/steep-views.md), and reports that sigma."""
        bound = self.settings.max_contrast_tip_sigma_m if max_sigma_m is None else float(max_sigma_m)
        self._gate_residual = float("nan")
        if not res.ok or not np.isfinite(bound):
            return res
        t = time.perf_counter()
        got = self._contrast_sigmas(res, views, contrast_noise)
        sigma = 0.0 if got is None else self._sigma_at(res, got)
        self._gate_residual = float("nan") if got is None else got[3]
        if sigma > 0:  # 0: the gate does not apply (no fit, or corners too close together)
            res = replace(res, tip_sigma_m=self._reported_sigma(res, views, contrast_noise, sigma))
        elif small_fits and np.isfinite(self.settings.max_small_fit_tip_sigma_m):
            small = self._small_fit_sigma(res, views)
            if small > 0:
                res = replace(res, tip_sigma_m=small)
            if small > self.settings.max_small_fit_tip_sigma_m:
                res.timings["contrast_gate"] = 1e3 * (time.perf_counter() - t)
                return replace(res, ok=False, tip_left=None, tip_world=None, T_left_marker=None, reason=(
                    f"the tip is uncertain by {1e3 * small:.2f} mm {_SMALL_FIT_CAUSE} "
                    "(corners that fit worse than a small marker's corners do)"))
        res.timings["contrast_gate"] = 1e3 * (time.perf_counter() - t)
        if sigma <= bound:
            return res
        return replace(res, ok=False, tip_left=None, tip_world=None, T_left_marker=None, reason=(
            f"the tip is uncertain by {1e3 * sigma:.2f} mm {_CONTRAST_GATE_CAUSE} "
            "(dim corners, or corners that fit worse than their contrast says)"))

    def _edge_refined(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]]) -> TrackResult:
        """A good, oriented result solved again from its corners and the centre lines of the
        print's dark bars found in both views near its pose (cvs.tracking.print_edges; a coded
        sleeve's code cells only where its roll is known), each bar sample at ``edge_sigma_px``.
        Not where the chains' median spacing is under ``edge_min_spacing_px``. Kept where at
        least ``edge_min_samples`` bar samples were found and both the corners and the bars
        reproject within ``edge_max_rms_px`` [px] RMS; the contrast gate still judges the
        corners' own fit (``pose.T_fit``)."""
        fit = self._edge_fit(res, views)
        return res if fit is None else fit[0]

    def _edge_fit(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]]
                  ) -> tuple[TrackResult, Corners, Bars] | None:
        """:meth:`_edge_refined`'s work: the refined result with the corners (points in the
        result's {wm}, pixels, solve noise) and bars it was solved from; None where it is not
        refined."""
        m, pose, s = res.match, res.pose, self.settings
        if m is None or pose is None or res.T_left_marker is None:
            return None
        if _median_spacing(res.corners_left, res.corners_right) < s.edge_min_spacing_px:
            return None
        t = time.perf_counter()
        T0 = np.asarray(res.T_left_marker, float)
        inv0 = np.eye(4)
        inv0[:3, :3], inv0[:3, 3] = T0[:3, :3].T, -T0[:3, :3].T @ T0[:3, 3]
        to_wm = inv0 @ pose.T_fit
        kl, kr = m.index_left >= 0, m.index_right >= 0
        in_l, in_r = np.asarray(pose.inliers_left, bool), np.asarray(pose.inliers_right, bool)
        own = res.corner_sigmas
        corners = []
        for idx, uv, inl, k, side in ((m.index_left, res.corners_left, in_l, kl, 0),
                                      (m.index_right, res.corners_right, in_r, kr, 1)):
            P = self.solver.marker_points(idx[k][inl]) @ to_wm[:3, :3].T + to_wm[:3, 3]
            sig = (own[side][inl] if own is not None and own[side].size == inl.size
                   else np.full(int(inl.sum()), s.corner_sigma_px))
            corners.append((P, uv[k][inl], np.asarray(sig, float)))
        if self._print_edges is None:
            self._print_edges = printed_edges(self.marker)
        edges = self._print_edges
        use = None if res.roll_known else ~edges.coded
        if not res.roll_known and print_is_negative(views[0], self.camera, T0, self.marker):
            edges = replace(edges, across=-edges.across)  # roll known modulo one column: the print's negative
        found = [measure_edges(views[i], self.camera, i == 1, T0, edges, use, blur_fit_px=s.edge_blur_fit_px,
                               blur_fit_max_sigma_px=s.edge_blur_max_sigma_px) for i in (0, 1)]
        bars = (bar_pairs(edges, found[0]), bar_pairs(edges, found[1]))
        if bars[0][0].shape[0] + bars[1][0].shape[0] < s.edge_min_samples:
            res.timings["edges"] = 1e3 * (time.perf_counter() - t)
            return None
        both = (corners[0], corners[1])
        T, rc, re = refine_with_edges(self.camera, T0, both, bars, s.edge_sigma_px)
        res.timings["edges"] = 1e3 * (time.perf_counter() - t)
        sig_all = np.concatenate([c[2] for c in corners])
        corner_rms = float(np.sqrt(np.mean((rc.reshape(-1, 2) * sig_all[:, None]) ** 2))) if rc.size else 0.0
        edge_rms = float(np.sqrt(np.mean(re ** 2)))
        if not (corner_rms <= s.edge_max_rms_px and edge_rms <= s.edge_max_rms_px):
            return None
        tip_left, tip_world = self.solver._tips(T)
        return (replace(res, T_left_marker=T, tip_left=tip_left, tip_world=tip_world,
                        pose=replace(pose, T_left_marker=T, tip_left=tip_left, tip_world=tip_world)), both, bars)

    def _retry_with_bars(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]], t0: float,
                         hint: Array | None) -> TrackResult:
        """A pair refused by the tip-sigma gate (too few corners, or seen too steeply, to fix
        the sleeve's tilt) taken as it would have been, oriented and refined with the print's
        bars (:meth:`_edge_fit`), and judged again with the bars' evidence added to the corners':
        kept where the tip's sigma at the corners' gate noise is within ``max_tip_sigma_m`` and
        at their contrast noise within ``max_contrast_tip_sigma_m``
        (cvs.tracking.print_edges.edges_tip_sigma). ``res`` unchanged otherwise."""
        m, best, s = res.match, res.pose, self.settings
        if m is None or best is None or s.edge_sigma_px <= 0 or not s.bars_gate:
            return res
        t = time.perf_counter()
        kl, kr = m.index_left >= 0, m.index_right >= 0
        idx_l, ul, idx_r, ur = m.index_left[kl], res.corners_left[kl], m.index_right[kr], res.corners_right[kr]
        if self._single_view_shift(best, idx_l, ul, idx_r, ur, m) > s.max_single_view_shift_m:
            return res
        cand = TrackResult(True, "", best.tip_left, best.tip_world, best.T_left_marker, res.corners_left,
                           res.corners_right, best.rms_px, 0.0, dict(res.timings), pose=best, match=m)
        cand = self._orient(cand, views, hint)
        if cand.ok and s.solve_contrast_noise > 0:
            cand = self._contrast_weighted(cand, views)
        fit = self._edge_fit(cand, views) if cand.ok else None
        if fit is None:
            res.timings["bars_gate"] = 1e3 * (time.perf_counter() - t)
            return res
        out, corners, bars = fit
        assert out.T_left_marker is not None and out.pose is not None
        tip = np.asarray(self.marker.tip(), float)
        tips, T = np.stack([tip, -tip]), out.T_left_marker
        in_l, in_r = np.asarray(out.pose.inliers_left, bool), np.asarray(out.pose.inliers_right, bool)
        gate_sig = [corner_sigmas(view, c[used], s.corner_sigma_px, s.corner_contrast_noise, s.clipped_sigma_px,
                                  s.clipped_level, s.clipped_radius * _median_spacing(c))
                    for view, c, used in ((views[0], ul, in_l), (views[1], ur, in_r))]

        def at(noise: tuple[Array, Array] | list[Array]) -> float:  # the tip's sigma at these corner noises
            return edges_tip_sigma(self.camera, T, ((corners[0][0], corners[0][1], noise[0]),
                                                     (corners[1][0], corners[1][1], noise[1])),
                                   bars, s.edge_sigma_px, tips)

        sigma = at(gate_sig)
        contrast = self._contrast_sigmas(out, views, None)
        c_sigma = 0.0
        if contrast is not None and np.isfinite(s.max_contrast_tip_sigma_m):
            c_sigma = at((contrast[3] * contrast[2][0], contrast[3] * contrast[2][1]))
        res.timings["bars_gate"] = out.timings["bars_gate"] = 1e3 * (time.perf_counter() - t)
        if not (sigma <= s.max_tip_sigma_m and c_sigma <= s.max_contrast_tip_sigma_m):
            return res
        return replace(out, time_ms=1e3 * (time.perf_counter() - t0), tip_sigma_m=c_sigma if c_sigma > 0 else math.nan)

    def _retry_two_pairs(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                         t0: float) -> TrackResult:
        """A coded sleeve lost for too few corners: its pose from two stereo pairs and the print
        (cvs.tracking.two_pairs; TrackerSettings.two_pairs_*), kept where the best roll hypothesis
        wins by the margin, its code reads the same roll and the tip's sigma from corners and bars
        passes the bars gate's bounds. Where two chords give poses whose tips differ by more than
        ``max_tip_sigma_m``, neither. ``res`` unchanged otherwise."""
        s = self.settings
        chains = [getattr(d, "chains_of_two", None) for d in (self.detector_left, self.detector_right)]
        if self.decoder is None or s.two_pairs_min_bars <= 0 or s.edge_sigma_px <= 0 or not all(
                callable(c) for c in chains):
            return res
        t = time.perf_counter()
        left, right = (c(v) for c, v in zip(chains, views))  # type: ignore[misc]
        m = self.marker
        chords = stereo_chords(self.rectifier, left, right, 2.0 * m.radius * math.sin(0.5 * m.beta), s.max_dy_px)
        kept = self.judge_chords(views, chords[:_TWO_PAIRS_MAX_CHORDS], res.timings)
        res.timings["two_pairs"] = 1e3 * (time.perf_counter() - t)
        if not kept or any(np.linalg.norm(np.asarray(k.tip_left) - np.asarray(kept[0].tip_left)) > s.max_tip_sigma_m
                           for k in kept[1:]):
            return res
        out = kept[0]
        out.timings["two_pairs"] = res.timings["two_pairs"]
        return replace(out, time_ms=1e3 * (time.perf_counter() - t0))

    def judge_chords(self, views: tuple[NDArray[np.uint8], NDArray[np.uint8]], chords: Sequence[StereoChord],
                     timings: dict[str, float] | None = None) -> list[TrackResult]:
        """Each stereo chord of two corners (cvs.tracking.two_pairs.stereo_chords) on the grey
        ``views``: its best roll hypothesis, kept where it passes every gate of
        :meth:`_retry_two_pairs` (TrackerSettings.two_pairs_*); the results kept, in the chords'
        order (bench/two_pairs.py judges chords of tracked pairs this way)."""
        s, m = self.settings, self.marker
        if self.decoder is None or s.edge_sigma_px <= 0:
            return []
        if self._print_edges is None:
            self._print_edges = printed_edges(m)
        kept: list[TrackResult] = []
        for chord in chords:
            axis = axis_from_edges(self.camera, chord, m)
            fit = None if axis is None else roll_hypotheses(views, self.camera, m, self._print_edges, chord, axis,
                                                            s.corner_sigma_px, s.edge_sigma_px, s.two_pairs_margin,
                                                            0.5 * s.max_tip_sigma_m)
            if fit is None or not (fit.bars >= s.two_pairs_min_bars and fit.bars >= fit.runner_up
                                   and fit.coded >= s.two_pairs_margin * max(fit.runner_up_coded, 1)
                                   and fit.corner_rms_px <= s.edge_max_rms_px and fit.bar_rms_px <= s.edge_max_rms_px):
                continue
            out = self._two_pair_result(fit, chord, views, {} if timings is None else timings)
            if out is not None:
                kept.append(out)
        return kept

    def _two_pair_result(self, fit: RollFit, chord: StereoChord, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                         timings: dict[str, float]) -> TrackResult | None:
        """:meth:`_retry_two_pairs`' judgement of one chord's best roll: its code read the same
        way (and, with a family, as this sleeve), both corners facing both cameras, and the tip's
        sigma from corners and bars within ``max_tip_sigma_m`` at the gate's corner noise and
        within ``max_contrast_tip_sigma_m`` at their contrast noise; the result, else None."""
        assert self.decoder is not None
        s, T = self.settings, fit.T_left_marker
        reading = self.decoder.read(views, T)
        if not (reading.ok and reading.shift == 0 and reading.direction > 0):
            return None
        if len(self.decoder.members) > 1 and self.decoder.members[reading.member] != self.marker:
            return None
        P = self.solver.marker_points(fit.ids)
        centres = (np.zeros(3), np.asarray(self._T_left_right[:3, 3], float))
        if min(float(corner_facing(T, P, c).min()) for c in centres) < s.min_corner_facing:
            return None
        tips = np.stack([np.asarray(self.marker.tip(), float), -np.asarray(self.marker.tip(), float)])
        uv = (chord.uv_left, chord.uv_right)
        gate_sig = [corner_sigmas(views[i], uv[i], s.corner_sigma_px, s.corner_contrast_noise, s.clipped_sigma_px,
                                  s.clipped_level, s.clipped_radius * _median_spacing(uv[i])) for i in (0, 1)]
        contrast = [corner_sigmas(views[i], uv[i], s.corner_sigma_px, s.gate_contrast_noise) for i in (0, 1)]
        chi2 = 0.0
        for project, u, sg in ((self.camera.project_left, uv[0], contrast[0]),
                               (self.camera.project_right, uv[1], contrast[1])):
            e = np.asarray(project(P @ T[:3, :3].T + T[:3, 3]), float).reshape(-1, 2) - u
            chi2 += float(((e / sg[:, None]) ** 2).sum())
        factor = max(1.0, math.sqrt(chi2 / 2.0))  # 8 residuals, 6 unknowns

        def at(noise: list[Array]) -> float:
            return edges_tip_sigma(self.camera, T, ((P, uv[0], noise[0]), (P, uv[1], noise[1])), fit.bar_pairs,
                                   s.edge_sigma_px, tips)

        c_sigma = at([factor * c for c in contrast])
        if not (at(gate_sig) <= s.max_tip_sigma_m and c_sigma <= s.max_contrast_tip_sigma_m):
            return None
        tip_left, tip_world = self.solver._tips(T)
        ids = np.asarray(fit.ids, int)
        rl, rr = self.rectifier.left(uv[0]), self.rectifier.right(uv[1])
        match = StereoMatch(ids.copy(), ids.copy(), np.array([[0, 0], [1, 1]]), np.asarray(chord.dy_px, float), rl, rr)
        inl = np.ones(2, bool)
        pose = MarkerPose(T, T, tip_left, tip_world, fit.corner_rms_px, 2, 2, inl, inl.copy(), self.marker.beta, 0.0)
        return TrackResult(True, "", tip_left, tip_world, T, uv[0].copy(), uv[1].copy(), fit.corner_rms_px, 0.0,
                           dict(timings), pose=pose, match=match, axis_source="code", roll_known=True,
                           ids_left=ids.copy(), ids_right=ids.copy(), code=reading,
                           tip_sigma_m=c_sigma)

    def _retry_with_gaps(self, res: TrackResult, t0: float) -> TrackResult:
        """A pair lost for too few corners: a highlight over the corner each camera sees best
        breaks the chain in two. One more try with the chains of each view's last search that
        step over a missed corner (cvs.corners.detector ``retry_with_gaps``: no new image search),
        under the same pose gates; ``res`` unchanged when that fails or the detectors cannot (its
        chains kept for :meth:`_retry_other_view`)."""
        retry = [getattr(d, "retry_with_gaps", None) for d in (self.detector_left, self.detector_right)]
        if not all(callable(r) for r in retry):
            return res
        t1 = time.perf_counter()
        chains = [r() for r in retry]  # type: ignore[misc]
        res2 = self.track_corners(chains[0].corners, chains[1].corners, chains[0].polarity, chains[1].polarity,
                                  _t0=t0)
        if not res2.ok:
            self._gap_chains = (chains[0], chains[1])
        out = res2 if res2.ok else res
        out.timings["gap_chain"] = 1e3 * (time.perf_counter() - t1)
        if res2.ok:
            out.timings[_GAP_FIT] = out.timings["gap_chain"]
        return out

    def _retry_other_view(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                          t0: float) -> TrackResult:
        """A pair still lost after every search whose chains stepping over a missed corner (kept by
        :meth:`_retry_with_gaps`) gave one view a chain and the other none: the other view searched
        where that chain's corners can appear (:func:`epipolar_box`, rays between
        ``other_view_depths_m``, grown by two spacings), its candidates down to
        ``other_view_cl_scale`` times the CL threshold (``retry_in_box``), under the same pose gates.
        Last, so that it never replaces a search that tracks the pair; ``res`` unchanged when it
        fails or does not apply."""
        s, chains, self._gap_chains = self.settings, self._gap_chains, None
        if chains is None or s.other_view_cl_scale <= 0:
            return res
        found = [c.corners.shape[0] >= s.min_corners for c in chains]
        seen = 0 if found[0] else 1
        search = getattr(self.detector_right if seen == 0 else self.detector_left, "retry_in_box", None)
        if found[0] == found[1] or not callable(search):
            return res
        t1 = time.perf_counter()
        uv = np.asarray(chains[seen].corners, float)
        spacing = float(np.median(np.linalg.norm(np.diff(uv, axis=0), axis=1)))
        box = epipolar_box(self.camera, uv, seen == 1, s.other_view_depths_m, 2.0 * spacing)
        if box is None:
            return res
        got = search(views[1 - seen], box, s.other_view_cl_scale)
        cl, cr = (chains[0], got) if seen == 0 else (got, chains[1])
        res2 = self.track_corners(cl.corners, cr.corners, cl.polarity, cr.polarity, _t0=t0)
        out = res2 if res2.ok else res
        out.timings["other_view"] = 1e3 * (time.perf_counter() - t1)
        if res2.ok:
            out.timings[_GAP_FIT] = out.timings["other_view"]
        return out

    def _retry_without_chain_ends(self, res: TrackResult, t0: float) -> TrackResult:
        """A pair whose corners did not fit the marker (reprojection RMS above ``max_rms_px``):
        one more try of each such set of chains with one end corner of one view's chain left out,
        where that view keeps ``min_corners``. A corner beside the marker's silhouette (grey sleeve
        against the background where the sleeve turns away, or its dark end face against the
        last row of squares) can pass the X-corner test and extend a chain by one: its relative
        index then shifts the view's others, and no pose fits them all (planar's cube, t = 2.12 s:
        3 + 3 true corners and one such corner, 1.14 px). The same pose gates; the fit with the
        lowest RMS is kept, ``res`` unchanged when none passes. The detectors' next ROIs follow
        the corners used."""
        t1 = time.perf_counter()
        n = self.settings.min_corners
        best: TrackResult | None = None
        best_sets: tuple[Array, Array] | None = None
        misfits, self._misfits = self._misfits, []
        for cl, cr, pl, pr in misfits:
            for view in (0, 1):
                c, p = (cl, pl) if view == 0 else (cr, pr)
                if c.shape[0] <= n:
                    continue
                for keep in (slice(1, None), slice(None, -1)):
                    c2, p2 = c[keep], None if p is None else p[keep]
                    use_l, use_r = (c2, cr) if view == 0 else (cl, c2)
                    pol_l, pol_r = (p2, pr) if view == 0 else (pl, p2)
                    r = self.track_corners(use_l, use_r, pol_l, pol_r, _t0=t0)
                    if r.ok and (best is None or r.rms_px < best.rms_px):
                        best, best_sets = r, (use_l, use_r)
        self._misfits = []
        out = best if best is not None else res
        out.timings["chain_end"] = 1e3 * (time.perf_counter() - t1)
        if best_sets is not None:
            for d, c in zip((self.detector_left, self.detector_right), best_sets):
                follow = getattr(d, "follow", None)
                if callable(follow):
                    follow(c)
        return out

    def _judged(self, res: TrackResult, views: tuple[Any, Any], hint: Array | None, gate: bool) -> TrackResult:
        """A good fit oriented (timings key 'axis'), solved again with each corner weighted by its
        contrast, refined with the print's bars and, with ``gate``, held to :meth:`contrast_gate`
        (refused there, the corners' ROIs stay, as for an ambiguous direction)."""
        t = time.perf_counter()
        self._gate_residual = float("nan")  # set by contrast_gate
        res = self._orient(res, views, hint)
        res.timings["axis"] = 1e3 * (time.perf_counter() - t)
        debias = self.settings.foreshortening_max_facing > 0
        if res.ok and self.settings.solve_contrast_noise > 0:
            res = self._contrast_weighted(res, views, debias)
        elif res.ok and debias:
            res = self._foreshortening_debiased(res)
        if res.ok and self.settings.edge_sigma_px > 0:
            res = self._edge_refined(res, views)
        if res.ok and gate:
            res = self.contrast_gate(res, views, small_fits=True)
        return res

    def _retry_wide_windows(self, res: TrackResult, views: tuple[Any, Any], t0: float,
                            hint: Array | None) -> TrackResult:
        """A fit :meth:`contrast_gate` refused whose corners lie further apart than the detector's
        HTM window serves (Gaussian weights 0.12 times the distance to the nearest other corner,
        capped at 4 px): its matched corners fitted again with the cap at ``wide_sigma_px``, in a
        window of 1.25 times that, at the fit's own edge directions (each corner's polarity from
        its index's parity), then solved, oriented and judged again under every gate. A large
        corner blurred by defocus is otherwise fitted from its noisy centre alone: path-traced
        808/19, 50-55 px between corners, fitted 0.4-1.3 px off and refused at 0.81 mm of tip
        sigma, is 0.2-0.8 px off and 0.10 mm off at the tip this way. ``res`` unchanged when no
        corner is that far apart or the new fit fails (timings key 'wide')."""
        s, m = self.settings, res.match
        if m is None or res.pose is None or s.wide_sigma_px <= HTM_WEIGHT_MAX_PX:
            return res
        kl, kr = m.index_left >= 0, m.index_right >= 0
        gaps = np.concatenate([nearest_spacing(c) for c in (res.corners_left[kl], res.corners_right[kr])])
        if not np.any(np.isfinite(gaps) & (HTM_WEIGHT_PER_SPACING * gaps > HTM_WEIGHT_MAX_PX)):
            return res
        t = time.perf_counter()
        radius = int(np.ceil(1.25 * s.wide_sigma_px))
        matched = replace(res, corners_left=res.corners_left[kl], corners_right=res.corners_right[kr],
                          match=replace(m, index_left=m.index_left[kl], index_right=m.index_right[kr]))
        parity = (np.where(m.index_left[kl] % 2 == 0, 1.0, -1.0), np.where(m.index_right[kr] % 2 == 0, 1.0, -1.0))
        again = self._refit_matched(matched, views, parity, t0,  # refit_corners converts its crops alone
                                    lambda view, uv, edges: refit_corners(view, uv, edges, radius, s.wide_sigma_px))
        if again is not None and again.ok:
            if _GAP_FIT in res.timings:  # the same corners' indices, guessed across a gap
                again.timings[_GAP_FIT] = res.timings[_GAP_FIT]
            again = self._judged(again, views, hint, gate=True)
        out = again if again is not None and again.ok else res
        out.timings["wide"] = 1e3 * (time.perf_counter() - t)
        return out

    def _wide_if_surer(self, res: TrackResult, views: tuple[Any, Any], t0: float, hint: Array | None) -> TrackResult:
        """A good result whose contrast gate found it reprojecting more than
        ``settings.wide_residual_factor`` times its corners' contrast noise: its corners fitted again
        in wide windows as a refused fit's are (:meth:`_retry_wide_windows`), the new result kept
        where it passes every gate and reports a smaller tip sigma. Defocused corners far apart,
        fitted from their noisy centres, do not fit each other: on the path-traced sets 2020-2727
        (1080p) this took 9 tips 0.01-0.19 mm nearer the truth and 2 others 0.07-0.09 mm further
        off (docs/notes/highlight-stripe.md)."""
        again = self._retry_wide_windows(res, views, t0, hint)
        return again if again is not res and again.tip_sigma_m < res.tip_sigma_m else res

    def _retry_partners(self, res: TrackResult, views: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                        t0: float) -> TrackResult:
        """Fits of this pair refused as hinging on corners seen in one view only (a highlight
        over a corner in the other view, where the chain stepped over it): each such corner is
        looked for in the other view where the refused fit puts it (cvs.tracking.corner_refit.
        partner_corners, at the fit's own edge directions; kept where it lands within
        ``partner_max_px`` of that place), and the chains with the partners found are solved
        again under every gate (a partner beside clipped pixels counts as ``clipped_sigma_px``
        noisy in the tip-sigma gate). The fit with the lowest RMS is kept; ``res`` unchanged when
        none passes (timings key 'partners')."""
        t1 = time.perf_counter()
        s = self.settings
        hinged, self._hinged = self._hinged, []
        best: TrackResult | None = None
        T_rl = np.eye(4)
        T_rl[:3, :3], T_rl[:3, 3] = self.camera.R, self.camera.T
        for cl, cr, pl, pr, fit, m in hinged:
            corners, pols = [np.asarray(cl, float), np.asarray(cr, float)], [np.asarray(pl), np.asarray(pr)]
            own = (m.index_left, m.index_right)
            added = 0
            for view, project, T_cam in ((0, self.camera.left.project, fit.T_fit),
                                         (1, self.camera.right.project, T_rl @ fit.T_fit)):
                other = 1 - view
                seen = own[view][own[view] >= 0]
                only = [j for j in range(own[other].size) if own[other][j] >= 0 and own[other][j] not in seen]
                if not only or corners[view].shape[0] < 2:
                    continue
                idx = own[other][only]
                P = self.solver.marker_points(idx)
                C = P @ T_cam[:3, :3].T + T_cam[:3, 3]
                uv = np.asarray(project(C), float).reshape(-1, 2)
                edges = corner_edge_angles(T_cam, P, project)
                gaps = np.linalg.norm(uv[:, None] - corners[view][None], axis=2).min(axis=1)
                found, ok = partner_corners(views[view], uv, edges, gaps, s.clipped_level,
                                            s.paper_detector.refine_radius,
                                            window_sigmas=s.paper_detector.refine_window_sigmas)
                ok &= np.linalg.norm(found - uv, axis=1) <= s.partner_max_px
                if ok.any():
                    corners[view] = np.vstack([corners[view], found[ok]])
                    pols[view] = np.concatenate([pols[view], pols[other][np.asarray(only)[ok]]])
                    added += int(ok.sum())
            if not added:
                continue
            r = self.track_corners(corners[0], corners[1], pols[0], pols[1], _t0=t0)
            if r.ok and (best is None or r.rms_px < best.rms_px):
                best = r
        self._hinged = []
        out = best if best is not None else res
        out.timings["partners"] = 1e3 * (time.perf_counter() - t1)
        return out

    def _retry_magnified(self, res: TrackResult, il: Any, ir: Any, t0: float) -> tuple[TrackResult, bool]:
        """A pair lost for too few corners (or a fit on too few to trust) where both views saw the
        marker in an earlier pair: each view's box around its last good corners searched once more
        enlarged ``settings.magnify`` times (bicubic): a small or steeply seen sleeve's squares, a
        few pixels wide, can fail the X-corner test at the image's own scale and pass it enlarged
        (docs/notes/steep-views.md). The same pose gates; ``res`` unchanged when that fails.
        Returns the result and whether it is the enlarged search's."""
        k = self.settings.magnify
        seen_l, seen_r = self._seen
        if k <= 1.0 or not self._magnifies or seen_l is None or seen_r is None:
            return res, False
        t1 = time.perf_counter()
        chains = [d.detect(img, _box_around(c, img.shape), magnify=k)  # type: ignore[call-arg]
                  for d, img, c in zip((self.detector_left, self.detector_right), (il, ir), (seen_l, seen_r))]
        res2 = self.track_corners(chains[0].corners, chains[1].corners, chains[0].polarity, chains[1].polarity,
                                  _t0=t0)
        out = res2 if res2.ok else res
        out.timings["magnified"] = 1e3 * (time.perf_counter() - t1)
        return out, res2.ok

    def _first_detector_in_boxes(self, res: TrackResult, il: NDArray[np.uint8], ir: NDArray[np.uint8],
                                 t0: float, polarity: tuple[Array | None, Array | None] = (None, None)
                                 ) -> TrackResult:
        """A good whole-frame result of the second detector ('auto'), its chains searched again by
        the first detector in each view's box around them, as the next pair's ROI search would:
        that result when it is good too (the first detector's corners are the finer: three arms,
        seed 4, pair 0 of sequence 4, arm c, the saddle's 0.26 mm against 0.017 mm from the same
        images' boxes; docs/notes/several-arms.md), else ``res``, the first detector's next boxes
        then around its corners (not around what the first detector chained in the whole frames),
        each fitted again by the first detector's model where that result is good too
        (:meth:`_refit_second`; ``polarity``: the second detector's, left and right)."""
        dets = (self.detector_left, self.detector_right)
        for d, c in zip(dets, (res.corners_left, res.corners_right)):
            d.follow(c)
        t1 = time.perf_counter()
        boxes = (self.detector_left.previous_roi(il.shape), self.detector_right.previous_roi(ir.shape))
        if boxes[0] is None or boxes[1] is None:
            return res
        chains = [d.detect(img, b) for d, img, b in zip(dets, (il, ir), boxes)]
        n = self.settings.min_corners
        if min(len(c.corners) for c in chains) >= n:
            again = self.track_corners(chains[0].corners, chains[1].corners, chains[0].polarity, chains[1].polarity,
                                       _t0=t0)
            if again.ok:
                again.timings["first_detector_boxes"] = 1e3 * (time.perf_counter() - t1)
                return again
        for d, c in zip(dets, (res.corners_left, res.corners_right)):  # its boxes stay on the second's chains
            d.follow(c)
        return self._refit_second(res, (il, ir), polarity, t0)

    def _refit_second(self, res: TrackResult, views: tuple[Any, Any], polarity: tuple[Array | None, Array | None],
                      t0: float) -> TrackResult:
        """A good result of the second detector (the saddle's coarser corners) with each matched
        corner fitted again by the first detector's HTM model at the fit's own edge directions
        (cvs.tracking.corner_refit), solved again under the same gates: that result when it is
        good, else ``res``. The saddle's chain through a corner whose edge a highlight bends, the
        paper detector's accuracy (path-traced seed 404 pair 41: 0.06-0.50 px -> 0.05-0.18)."""
        d = self.settings.paper_detector
        again = self._refit_matched(res, views, polarity, t0, lambda view, uv, edges: refit_corners(
            view, uv, edges, d.refine_radius, window_sigmas=d.refine_window_sigmas))
        if again is None:
            return res
        out = again if again.ok else res
        out.timings["second_refit"] = again.timings.pop("refit", 0.0)
        return out

    def _retry_eroded(self, res: TrackResult, il: Any, ir: Any, t0: float) -> TrackResult:
        """A pair lost for too few corners (or no start pose) whose views clip, after every other
        search (the reduced one tracks 4 of the 6 path-traced pairs this search does, at a
        fraction of its cost, and runs first): white squares
        exposed at several times full scale and blurred spread over the corners, and no corner
        passes the X-corner test (a sleeve close to the lens: path-traced seed 303 pairs 47 and
        55, seed 404 pair 49). Each view eroded (a grey-level minimum over a disc of each size in
        ``settings.eroded_sizes`` [px] in turn) grows the dark squares back until they touch; the
        first detector's chains there give a pose, and each matched corner is then fitted on the
        view itself by the HTM model with its clipped pixels censored
        (cvs.corners.clipped_fit), and solved again under the same gates and one more: the tip's
        standard deviation with every corner at ``clipped_sigma_px`` within ``max_tip_sigma_m``
        (seed 303 pair 10, eroded, was 0.58 mm off at 1.7 mm of it; the pairs kept 0.34-0.89 mm,
        0.05-0.15 mm off). The first size whose refitted corners pass is kept (the eroded
        corners alone, 0.1-1.9 px off, never are), and
        is tried first on the next such pair; ``res`` when none does, or when a view has fewer
        than ``eroded_min_clipped_px`` pixels at ``clipped_level`` or more (erosion finds nothing
        new in a view that does not clip)."""
        s = self.settings
        if not s.eroded_sizes:
            return res
        t1 = time.perf_counter()
        gl, gr = to_gray(il), to_gray(ir)
        if min(int(np.count_nonzero(gl >= s.clipped_level)), int(np.count_nonzero(gr >= s.clipped_level))) \
                < s.eroded_min_clipped_px:
            return res
        out = res
        sizes = [int(k) for k in s.eroded_sizes]
        if self._eroded_size in sizes:  # the size that tracked the last such pair first
            sizes.remove(self._eroded_size)
            sizes.insert(0, self._eroded_size)
        self._eroded_size = 0
        for size in sizes:
            disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (int(size), int(size)))
            dl = self.detector_left.detect(cv2.erode(gl, disc))
            dr = self.detector_right.detect(cv2.erode(gr, disc))
            first = self.track_corners(dl.corners, dr.corners, dl.polarity, dr.polarity, _t0=t0)
            if not first.ok:
                continue
            again = self._refit_matched(first, (gl, gr), (dl.polarity, dr.polarity), t0, self._refit_clipped)
            if again is not None and again.ok and self._clipped_tip_sigma(again) <= s.max_tip_sigma_m:
                again.timings["eroded_refit"] = again.timings.pop("refit", 0.0)
                out, self._eroded_size = again, size
                for d, c in zip((self.detector_left, self.detector_right), (again.corners_left, again.corners_right)):
                    d.follow(c)
                break
        out.timings["eroded"] = 1e3 * (time.perf_counter() - t1)
        return out

    def _retry_reduced(self, res: TrackResult, il: Any, ir: Any, t0: float) -> TrackResult:
        """A pair lost for too few corners, no start pose or a fit on too few corners (after the
        partners, before the eroded search: the cheaper first), searched once more in each whole
        view reduced by each factor of ``settings.reduced_scales`` in turn
        (cvs.corners.detector.MarkerCornerDetector.detect_reduced): a sleeve close to the lens or
        out of focus, its corners blurred over several pixels, fails the X-corner test at full and
        half scale (path-traced seed 606 pair 30: no X-corner at all, corners 80 px apart) and
        can pass it there. Each matched corner is then fitted on the view itself by the HTM model
        with its clipped pixels censored (its window 0.3 times the spacing, up to 14 px:
        cvs.corners.clipped_fit; a corner whose window does not clip keeps its place from the
        reduced view: a plain HTM fit in the same window was further off on the path-traced pairs)
        and solved again under the same gates and the clipped-noise tip gate (as
        :meth:`_retry_eroded`); the first factor whose refitted corners pass is kept, else
        ``res``. With ``settings.reduced_sigma_px`` (> 0), where no factor passes so, the first
        fit that passes both tip-sigma gates with every corner at that noise (as measured for this
        search's corners, beside clipped pixels or not) is kept for :meth:`_last_resort`; every
        result of this search reports its sigma at that noise (:meth:`_reported_sigma`). Paper
        detector only (not the saddle)."""
        scales = self.settings.reduced_scales
        dets = (self.detector_left, self.detector_right)
        if not scales or not all(hasattr(d, "detect_reduced") for d in dets):
            return res
        t1 = time.perf_counter()
        gl, gr = to_gray(il), to_gray(ir)
        measured = self.settings.reduced_sigma_px or None  # None: no last resort
        out = res
        for k in scales:
            dl, dr = (d.detect_reduced(g, k) for d, g in zip(dets, (gl, gr)))  # type: ignore[attr-defined]
            for noise in (None, measured) if measured and self._reduced_last_resort is None else (None,):
                first = self.track_corners(dl.corners, dr.corners, dl.polarity, dr.polarity, _t0=t0,
                                           _noise_px=noise)
                if not first.ok:
                    continue
                again = self._refit_matched(first, (gl, gr), (dl.polarity, dr.polarity), t0, self._refit_clipped,
                                            noise)
                if (again is None or not again.ok
                        or self._clipped_tip_sigma(again, noise) > self.settings.max_tip_sigma_m):
                    continue
                again.timings["reduced_refit"] = again.timings.pop("refit", 0.0)
                if noise is not None:  # passes only at the measured noise: kept for the end
                    self._reduced_last_resort = again
                    break
                out = again
                self._reduced_last_resort = None
                for d, c in zip(dets, (again.corners_left, again.corners_right)):
                    d.follow(c)
                break
            if out is not res:
                break
        out.timings["reduced"] = 1e3 * (time.perf_counter() - t1)
        return out

    def _last_resort(self, res: TrackResult, views: tuple[Any, Any], hint: Array | None, gate: bool) -> TrackResult:
        """``res`` (lost after every search) or, where the reduced search found a fit that passes
        its tip-sigma gates only with its corners at ``settings.reduced_sigma_px`` (their measured
        noise) rather than at ``clipped_sigma_px`` beside clipped pixels, that fit oriented and
        judged (:meth:`_judged`); kept for the end so that it never takes the place of a pair
        another search tracks (held-out path-traced 2626/26: 0.13 mm off at 0.74 mm of sigma)."""
        fit, self._reduced_last_resort = self._reduced_last_resort, None
        if fit is None or res.ok:
            return res
        for d, c in zip((self.detector_left, self.detector_right), (fit.corners_left, fit.corners_right)):
            d.follow(c)
        fit.timings.update({k: v for k, v in res.timings.items() if k not in fit.timings})
        return self._judged(fit, views, hint, gate)

    def _refit_clipped(self, view: Any, uv: Array, edges: Array) -> Array:
        """The corners ``uv`` [px] of the grey ``view`` fitted again by the HTM model with the
        pixels at ``settings.clipped_level`` or more censored (cvs.tracking.corner_refit)."""
        return refit_corners_clipped(view, uv, edges, float(self.settings.clipped_level))[0]

    def _clipped_tip_sigma(self, res: TrackResult, corner_sigma_px: float | None = None) -> float:
        """The tip's standard deviation [m] of a good result's fit with every used corner at
        ``corner_sigma_px`` of noise, by default ``settings.clipped_sigma_px``: corners between
        clipped white squares are 0.3-0.8 px off where the two squares' exposures differ
        (cvs.corners.clipped_fit)."""
        m, pose = res.match, res.pose
        if m is None or pose is None:
            return float("inf")
        noise = self.settings.clipped_sigma_px if corner_sigma_px is None else corner_sigma_px
        return self._tip_sigma(pose, m.index_left[m.index_left >= 0], m.index_right[m.index_right >= 0],
                               corner_sigma_px=noise)

    def _refit_matched(self, res: TrackResult, views: tuple[Any, Any], polarity: tuple[Array | None, Array | None],
                       t0: float, refit: Callable[[Any, Array, Array], Array],
                       noise_px: float | None = None) -> TrackResult | None:
        """``res``'s matched corners, each fitted again by ``refit(view, uv, edges)`` at the fit's
        own edge directions (cvs.tracking.corner_refit.corner_edge_angles), solved again under
        the same gates (timings key 'refit'; ``noise_px``: as :meth:`track_corners`'s
        ``_noise_px``); None when ``res`` has no fit."""
        m, pose = res.match, res.pose
        if m is None or pose is None:
            return None
        t = time.perf_counter()
        T_rl = np.eye(4)
        T_rl[:3, :3], T_rl[:3, 3] = self.camera.R, self.camera.T
        refit_uv: list[Array] = []
        for view, project, T_cam, corners, index in zip(
            views, (self.camera.left.project, self.camera.right.project), (pose.T_fit, T_rl @ pose.T_fit),
            (res.corners_left, res.corners_right), (m.index_left, m.index_right),
        ):
            out = np.array(corners, float).reshape(-1, 2)
            k = index >= 0
            if k.any():
                out[k] = refit(view, out[k], corner_edge_angles(T_cam, self.solver.marker_points(index[k]), project))
            refit_uv.append(out)
        again = self.track_corners(refit_uv[0], refit_uv[1], polarity[0], polarity[1], _t0=t0, _noise_px=noise_px)
        again.timings["refit"] = 1e3 * (time.perf_counter() - t)
        return again

    def _second_detectors(self) -> tuple[CornerDetector, CornerDetector]:
        """The saddle detector of each view ('auto': the second try), made on first use."""
        if self._second is None:
            self._second = (make_detector("saddle"), make_detector("saddle"))
        return self._second

    def _track_in_rois(self, il: Any, ir: Any, t0: float, whole: bool = True) -> tuple[TrackResult | None,
                                                                                          tuple[Any, Any]]:
        """ROI tracking (paper III.A(1)): each view's detector in the box around its previous
        corners. A view whose box misses the marker is searched whole, after (with 'auto') one try of
        the second detector in both views' boxes: a miss of one detector in one view (the paper's
        detector lost 1-2 % of the lab's frames at half size that the saddle detector found at once)
        then costs two small boxes, not a whole-frame search of both views with both detectors (80-
        100 ms at 960 x 540, the servo loop's cycle overrun). Boxes that both chain corners that
        give no good fit (a small sleeve's box also holds the edges beside it: the scene lab's sleeve
        at half size, 20 px between corners, in most pairs of its start) get the same try when the
        whole frames are not to be searched (``whole`` False: the arm set's ROI phase); else the
        first detector's whole frames come first, in :meth:`_track_views`. Returns the result (None
        when neither view has a box) and the chains of the views searched whole here (None where
        not)."""
        n = self.settings.min_corners
        boxes = (self.detector_left.previous_roi(il.shape), self.detector_right.previous_roi(ir.shape))
        if boxes[0] is None and boxes[1] is None:
            return None, (None, None)
        dets = (self.detector_left, self.detector_right)
        mag = {"magnify": self._roi_magnify} if self._roi_magnify > 1.0 and self._magnifies else {}
        chains: list[Any] = [None if b is None else d.detect(img, b, **mag) for d, img, b in zip(dets, (il, ir), boxes)]
        missed = [c is None or len(c.corners) < n for c in chains]
        self._continuous = not any(missed)  # the previous pose is a start and a prior only then
        if not any(missed):
            t_det = 1e3 * (time.perf_counter() - t0)
            res = self.track_corners(chains[0].corners, chains[1].corners, chains[0].polarity, chains[1].polarity,
                                     _t0=t0)
            res.timings["detect"] = t_det
            if res.ok:
                return res, (None, None)
            # each box chained corners, but not the marker's; with the whole frames to search, the
            # first detector's come first (its corners are the finer where they fit)
            if whole:
                return res, (None, None)
            second_res = self._second_in_boxes_kept(il, ir, boxes, t0)
            return (res if second_res is None else second_res), (None, None)
        if (second_res := self._second_in_boxes(il, ir, boxes, t0)) is not None:
            return second_res, (None, None)
        full: list[Any] = [None, None]
        for k in (0, 1):
            if missed[k] and whole:  # that view whole, as the detector's own ``track`` would
                full[k] = chains[k] = dets[k].detect(to_gray((il, ir)[k]))
        t_det = 1e3 * (time.perf_counter() - t0)
        dl, dr = chains
        if dl is None or dr is None:  # roi_only, and one view had no box
            return self._fail("a view has no ROI to search (roi_only)", np.zeros((0, 2)), np.zeros((0, 2)), t0,
                              {"detect": t_det}), (None, None)
        res = self.track_corners(dl.corners, dr.corners, dl.polarity, dr.polarity, _t0=t0)
        res.timings["detect"] = t_det
        return res, (full[0], full[1])

    def _second_in_boxes_kept(self, il: Any, ir: Any, boxes: tuple[Any, Any], t0: float) -> TrackResult | None:
        """:meth:`_second_in_boxes` with the first detector searching again around the second's
        chains; when it fails, the retries that follow see the pair's earlier chains alone (the
        misfits and hinges its own fits left are dropped)."""
        kept = (self._misfits, self._hinged, self._last_shift, self._last_fit_px)
        res = self._second_in_boxes(il, ir, boxes, t0, first_again=True)
        if res is None:
            self._misfits, self._hinged, self._last_shift, self._last_fit_px = kept
        return res

    def _second_in_boxes(self, il: Any, ir: Any, boxes: tuple[Any, Any], t0: float,
                         first_again: bool = False) -> TrackResult | None:
        """ROI tracking's one try of the second detector ('auto') in both views' boxes, when the
        first missed the marker in one of them or its chains gave no good fit: the good result
        (its corners fitted again by the first detector's model, :meth:`_refit_second`; the
        next pair's boxes follow it), or None. ``first_again``: the first detector searches
        again in boxes around the second's chains first (:meth:`_first_detector_in_boxes`)."""
        if not self._use_second or boxes[0] is None or boxes[1] is None:
            return None
        t1 = time.perf_counter()
        second = self._second_detectors()
        sl, sr = second[0].detect(il, boxes[0]), second[1].detect(ir, boxes[1])
        t_box = 1e3 * (time.perf_counter() - t1)
        if min(len(sl.corners), len(sr.corners)) < self.settings.min_corners:
            return None
        res = self.track_corners(sl.corners, sr.corners, sl.polarity, sr.polarity, _t0=t0)
        if not res.ok:
            return None
        polarity = (sl.polarity, sr.polarity)
        if first_again:  # its boxes follow the result
            res = self._first_detector_in_boxes(res, il, ir, t0, polarity)
        else:
            res = self._refit_second(res, (il, ir), polarity, t0)
            for d, c in zip((self.detector_left, self.detector_right), (sl, sr)):  # the next boxes follow it
                d.follow(c.corners)
        res.timings["detect"] = 1e3 * (time.perf_counter() - t0) - t_box
        res.timings["second_detector_roi"] = t_box
        return res

    def _single_view_shift(self, best: MarkerPose, idx_l: IntArray, ul: Array, idx_r: IntArray, ur: Array,
                           m: StereoMatch) -> float:
        """How far [m] the tip of the fit ``best`` lies from the best fit of the stereo pairs only,
        over the same start poses (0 when every corner has its partner, when fewer than 3 pairs
        leave the pairs' own fit no better determined than ``best``, or when they give no fit)."""
        if idx_l.size == idx_r.size and np.array_equal(np.sort(idx_l), np.sort(idx_r)):
            return 0.0  # every corner has its partner (the test below, without its set operations)
        common = np.intersect1d(idx_l, idx_r)
        in_l, in_r = np.isin(idx_l, common), np.isin(idx_r, common)
        if (in_l.all() and in_r.all()) or common.size < 3:
            return 0.0
        kept = (self._last_shift, self._last_fit_px)  # the previous start's bookkeeping is this pair's
        pairs_only: MarkerPose | None = None
        for T0 in self._start_poses(idx_l[in_l], ul[in_l], idx_r[in_r], ur[in_r], m):
            pose = self.solver.solve(idx_l[in_l], ul[in_l], idx_r[in_r], ur[in_r], T0)
            if np.isfinite(pose.rms_px) and (pairs_only is None or pose.rms_px < pairs_only.rms_px):
                pairs_only = pose
        self._last_shift, self._last_fit_px = kept
        if pairs_only is None:
            return 0.0
        # the fitted poses' tips (T_fit: the same sense of the indices in both; the reported tips may
        # differ by the half turn the axis prior applies to each fit on its own)
        tips = [self.solver._tips(pose.T_fit)[0] for pose in (pairs_only, best)]
        return float(np.linalg.norm(tips[0] - tips[1]))

    def _orient(self, res: TrackResult, images: tuple[NDArray[np.uint8], NDArray[np.uint8]],
                hint: Array | None) -> TrackResult:
        """Fix the direction of z_wm (and, with a readable code, the roll) of a good fit: the
        code (coded sleeves), a caller's hint, else the previous pair's pose where this fit is
        consistent with it and the image does not contradict it, else decisive image evidence
        that the arm-width evidence backs by ``decide`` (unbacked, it is marginal)
        (marginal evidence only where the default prior agrees, or where the arm-width evidence,
        ``AxisEvidenceSettings.arm_offsets``, decisively backs the prior against it: then the
        prior, with that score), else (not strict_direction) the default prior; otherwise ok
        false, 'direction ambiguous'."""
        assert res.pose is not None
        pose, score = res.pose, float("nan")
        if self.decoder is not None:
            t = time.perf_counter()
            reading = self.decoder.read(images, pose.T_fit)
            res.timings["code"] = 1e3 * (time.perf_counter() - t)
            res = replace(res, code=reading)
            if reading.ok and reading.T_fit_abs is not None:
                T = pose.T_fit @ reading.T_fit_abs
                tip_left, tip_world = self.solver._tips(T)
                pose = replace(pose, T_left_marker=T, tip_left=tip_left, tip_world=tip_world)
                m = res.match
                n = self.marker.columns
                ids_l = None if m is None else reading.absolute_ids(m.index_left, n)
                ids_r = None if m is None else reading.absolute_ids(m.index_right, n)
                return replace(res, tip_left=tip_left, tip_world=tip_world, T_left_marker=T, pose=pose,
                               axis_source="code", roll_known=True, ids_left=ids_l, ids_right=ids_r)
        z = pose.T_left_marker[:3, 2]
        want: Array | None = None
        source = "none"
        if hint is not None:
            want, source = np.asarray(hint, float).reshape(3), "hint"
        else:
            strict, ax = self.settings.strict_direction, self.settings.axis
            evidence = axis_evidence_strict if strict else axis_evidence
            prior = self._consistent_prior(pose)
            # with a consistent prior the image need only not contradict it: the left image suffices
            score = evidence(images, self.camera, self.marker, pose.T_left_marker, ax, left_only=prior is not None)
            decided = abs(score) >= (ax.decide_strict if strict else ax.decide)
            default = None if strict or self.settings.pose.axis_hint_left is None else np.asarray(
                self.settings.pose.axis_hint_left, float)
            width = float("nan")  # the same evidence at the arm's width alone, where asked for

            def arm_width() -> float:
                return evidence(images, self.camera, self.marker, pose.T_left_marker,
                                replace(ax, offsets=ax.arm_offsets, min_band_edge=ax.arm_min_edge))

            decisive = decided and (strict or abs(score) >= ax.decide + ax.margin)
            if prior is None and decisive and not strict and ax.arm_offsets:
                # decisive only where a body as wide as the arm shows on the same side (else
                # marginal): a lit, glossy tool's edges at 0.55-0.6 radii fooled it (2020/18, stop 62)
                width = arm_width()
                decisive = abs(width) >= ax.decide and (width > 0) == (score > 0)
            if prior is not None:
                if not decided or (score > 0) == (float(z @ prior) > 0):
                    want, source = prior, "previous"
            elif decisive:
                want, source = (z if score > 0 else -z), "image"
            elif decided:  # marginal: only with the default prior's agreement, else ambiguous
                if default is not None and (score > 0) == (float(z @ default) > 0):
                    want, source = (z if score > 0 else -z), "image"
                elif default is not None and ax.arm_offsets:  # unless a body as wide as the arm backs the prior
                    width = arm_width() if np.isnan(width) else width
                    if abs(width) >= ax.decide + ax.margin and (width > 0) == (float(z @ default) > 0):
                        want, source, score = default, "default", width
            elif default is not None:
                want, source = default, "default"
        if want is None:
            return replace(res, ok=False, reason="direction ambiguous", tip_left=None, tip_world=None,
                           T_left_marker=None, axis_source="", axis_score=score)
        if float(np.dot(z, want)) < 0:
            pose, score = self.solver.half_turned(pose), -score
        return replace(res, tip_left=pose.tip_left, tip_world=pose.tip_world, T_left_marker=pose.T_left_marker,
                       pose=pose, axis_source=source, axis_score=score)

    def _faces_cameras(self, pose: MarkerPose, idx_l: IntArray, idx_r: IntArray) -> bool:
        """Every corner the fit uses faces the camera that saw it (cvs.tracking.sleeve_facing;
        TrackerSettings.min_corner_facing): a fit with a corner on the far side of the sleeve is
        the arc turned inside out."""
        lim = self.settings.min_corner_facing
        T = pose.T_fit
        centres: tuple[Array, Array] = (np.zeros(3), np.asarray(self._T_left_right[:3, 3], float))
        for idx, used, centre in ((idx_l, pose.inliers_left, centres[0]), (idx_r, pose.inliers_right, centres[1])):
            P = self.solver.marker_points(np.asarray(idx)[np.asarray(used, bool)])
            if P.size and float(corner_facing(T, P, centre).min()) < lim:
                return False
        return True

    def _tip_sigma(self, pose: MarkerPose, idx_l: IntArray, idx_r: IntArray,
                   uv: tuple[Array, Array] | None = None, corner_sigma_px: float | None = None) -> float:
        """The fit's tip standard deviation [m] (cvs.tracking.tip_uncertainty), the larger of the
        sleeve's two ends (the direction of z_wm is decided later), at each used corner's noise:
        ``corner_sigma_px`` (default ``settings.corner_sigma_px``), and with the pair's images
        (``track``) and ``uv`` (the corners' raw pixels of each view, as idx_l / idx_r) combined
        with ``corner_contrast_noise`` / the corner's contrast and, beside clipped pixels,
        ``clipped_sigma_px`` (cvs.tracking.tip_uncertainty.corner_sigmas)."""
        P = self.solver.marker_points
        in_l, in_r = np.asarray(pose.inliers_left, bool), np.asarray(pose.inliers_right, bool)
        used_l, used_r = np.asarray(idx_l)[in_l], np.asarray(idx_r)[in_r]
        tip = np.asarray(self.marker.tip(), float)
        s = self.settings
        if corner_sigma_px is not None:
            return tip_sigma(self.camera, pose.T_fit, P(used_l), P(used_r), np.stack([tip, -tip]), corner_sigma_px)
        sigmas: tuple[Array, Array] | None = None
        if self._views is not None and uv is not None and (s.corner_contrast_noise > 0 or s.clipped_sigma_px > 0):
            sl, sr = (corner_sigmas(view, c[used], s.corner_sigma_px, s.corner_contrast_noise, s.clipped_sigma_px,
                                    s.clipped_level, s.clipped_radius * _median_spacing(c))
                      for view, c, used in ((self._views[0], uv[0], in_l), (self._views[1], uv[1], in_r)))
            sigmas = (sl, sr)
        return tip_sigma(self.camera, pose.T_fit, P(used_l), P(used_r), np.stack([tip, -tip]),
                         s.corner_sigma_px, sigmas)

    def _consistent_prior(self, pose: MarkerPose) -> Array | None:
        """The previous pair's z_wm direction in {ll} if it may serve as a prior for this fit:
        the chains were found in the previous ROIs, the previous direction was decided, and this
        fit moved little from the previous one (TrackerSettings.prior_*); else None."""
        prev = self._last_pose
        if not (self._continuous and self._last_oriented and prev is not None):
            return None
        s = self.settings
        T_prev = prev.T_fit @ roll_about_z(self._last_shift * self.marker.beta)  # in this pair's indices
        if np.linalg.norm(pose.T_fit[:3, 3] - T_prev[:3, 3]) > s.prior_max_move_m:
            return None
        dR = T_prev[:3, :3].T @ pose.T_fit[:3, :3]
        if np.degrees(np.arccos(np.clip((np.trace(dR) - 1.0) / 2.0, -1.0, 1.0))) > s.prior_max_turn_deg:
            return None
        if self._last_fit_px > s.prior_max_px:
            return None
        return np.asarray(prev.T_left_marker[:3, 2], float)

    @property
    def tracking(self) -> bool:
        """The next pair is searched first in the boxes around this pair's corners (ROI tracking)."""
        return self._tracking

    def adopt(self, res: TrackResult) -> None:
        """Go on tracking from a good result another tracker of the same marker layout found (its
        corners' boxes, its pose as the next pair's prior): cvs.tracking.arm_set hands a sleeve
        found in a search for another arm to its own arm's tracker."""
        if not res.ok or res.pose is None:
            raise InputError("only a good result can be adopted")
        self.detector_left.follow(res.corners_left)
        self.detector_right.follow(res.corners_right)
        self._tracking = self._last_oriented = True
        self._last_pose = res.pose
        self._seen, self._roi_magnify = (res.corners_left.copy(), res.corners_right.copy()), 1.0

    def reset(self) -> None:
        """Forget the ROI state: the next pair is searched in the whole frames."""
        self._tracking = self._continuous = self._last_oriented = False
        self._last_pose = None
        self._seen, self._roi_magnify = (None, None), 1.0
        self._eroded_size = 0

    def _start_poses(
        self, idx_l: IntArray, ul: Array, idx_r: IntArray, ur: Array, m: StereoMatch
    ) -> Iterator[Array]:
        """Start poses, most likely first, each computed only when the ones before it did not
        give a good fit: the previous pair's pose (tracking), the homography of the camera with
        more corners (paper eq. 14-15), both planar solutions of cv2 IPPE (the homography's
        mirror-tilt ambiguity) and triangulation + Kabsch; with only two stereo pairs (and at
        least four corners in all), their chord turned in 12 steps (rigid_fit ``chord_starts``)."""
        self._last_shift, self._last_fit_px = 0, float("inf")
        if self._continuous and self._last_pose is not None:
            yield self._previous_start(idx_l, ul)
        pts = self.solver.marker_points
        use_left = idx_l.size >= idx_r.size
        idx, uv, cam = (idx_l, ul, self.camera.left) if use_left else (idx_r, ur, self.camera.right)
        T_fix = np.eye(4) if use_left else self._T_left_right
        if idx.size >= 4:
            H: Array | None = None
            try:
                H = T_fix @ homography_pose(cam, pts(idx), uv)
            except (InputError, np.linalg.LinAlgError):
                pass
            if H is not None:
                yield H
            ippe: list[Array] = []
            try:
                n, rvecs, tvecs, _ = cv2.solvePnPGeneric(
                    pts(idx), uv, np.asarray(cam.K, float), np.asarray(cam.dist, float), flags=cv2.SOLVEPNP_IPPE
                )
                for rv, tv in zip(rvecs[:n], tvecs[:n]):
                    T = np.eye(4)
                    T[:3, :3], T[:3, 3] = cv2.Rodrigues(rv)[0], np.asarray(tv).reshape(3)
                    ippe.append(T_fix @ T)
            except cv2.error:
                pass
            yield from ippe
        if m.n_pairs >= 3:
            X = cv2.triangulatePoints(
                self.rectifier.P1, self.rectifier.P2, m.rect_left[m.pairs[:, 0]].T, m.rect_right[m.pairs[:, 1]].T
            )
            X = (X[:3] / X[3]).T @ np.asarray(self.rectifier.R1)  # rectified-left -> {ll}
            yield kabsch(pts(m.index_left[m.pairs[:, 0]]), X)
        elif m.n_pairs == 2 and idx.size < 4 and np.union1d(idx_l, idx_r).size >= 4:
            # two stereo pairs and single-view corners (a stripe over a corner in each view): the
            # pairs fix a chord, its turn is left to the solve from each of a few starts
            X = cv2.triangulatePoints(
                self.rectifier.P1, self.rectifier.P2, m.rect_left[m.pairs[:, 0]].T, m.rect_right[m.pairs[:, 1]].T
            )
            X = (X[:3] / X[3]).T @ np.asarray(self.rectifier.R1)
            yield from chord_starts(pts(m.index_left[m.pairs[:, 0]]), X)

    def _previous_start(self, idx: IntArray, uv: Array) -> Array:
        """The previous pair's fitted pose in this pair's relative indices. The chain's first
        corner can change from pair to pair (a corner appears or leaves at its end), which
        shifts the indices by an even k (polarity fixes the parity): the start is the previous
        pose rolled by the k beta that best puts its corners on this pair's left detections."""
        assert self._last_pose is not None
        T = self._last_pose.T_fit
        n, beta = self.marker.columns, self.marker.beta
        ks = np.arange(0, n, 2)
        P = np.concatenate([self.solver.marker_points(idx + k) for k in ks])  # {wm}, model index i + k
        proj = self.camera.project_left(P @ T[:3, :3].T + T[:3, 3]).reshape(ks.size, -1, 2)
        err = np.sqrt(((proj - uv[None]) ** 2).sum(axis=2).mean(axis=1))
        j = int(np.argmin(err))
        k = int(ks[j])
        self._last_shift, self._last_fit_px = k, float(err[j])
        return T @ roll_about_z(k * beta)  # maps model point i to where the previous pose had i + k

    def track_corners(
        self,
        corners_left: Array,
        corners_right: Array,
        polarity_left: Array | None = None,
        polarity_right: Array | None = None,
        _t0: float | None = None,
        _noise_px: float | None = None,
    ) -> TrackResult:
        """Pose and tip from raw-pixel corners (N, 2) of each image and optional polarities (+-1)
        (``_noise_px``: the tip-sigma gate counts every corner at this noise [px], the reduced
        search's; None: each at its own, as :meth:`_tip_sigma` says)."""
        t0 = time.perf_counter() if _t0 is None else _t0
        s = self.settings
        cl = np.asarray(corners_left, float).reshape(-1, 2)
        cr = np.asarray(corners_right, float).reshape(-1, 2)
        timings: dict[str, float] = {}
        if cl.shape[0] == 0 and cr.shape[0] == 0:
            return self._fail("no marker found in either image", cl, cr, t0, timings)
        if min(cl.shape[0], cr.shape[0]) < s.min_corners:
            return self._fail(
                f"too few marker corners (left {cl.shape[0]}, right {cr.shape[0]}; need {s.min_corners} each)",
                cl,
                cr,
                t0,
                timings,
            )
        t1 = time.perf_counter()
        pl = None if polarity_left is None else np.asarray(polarity_left, int)
        pr = None if polarity_right is None else np.asarray(polarity_right, int)
        m = match_corners(self.rectifier, cl, cr, pl, pr, s.max_dy_px)
        timings["match"] = 1e3 * (time.perf_counter() - t1)
        if m.n_pairs < s.min_pairs:
            return self._fail(
                f"only {m.n_pairs} left/right corner pairs (need {s.min_pairs})", cl, cr, t0, timings, match=m
            )
        kl, kr = m.index_left >= 0, m.index_right >= 0
        idx_l, ul, idx_r, ur = m.index_left[kl], cl[kl], m.index_right[kr], cr[kr]
        starts = self._start_poses(idx_l, ul, idx_r, ur, m)
        best: MarkerPose | None = None
        best_facing = False
        t_init = t_solve = 0.0
        while True:  # tracking: stop at a good fit from the previous pose; else the best of all starts
            t2 = time.perf_counter()
            T0 = next(starts, None)
            t3 = time.perf_counter()
            t_init += t3 - t2
            if T0 is None:
                break
            pose = self.solver.solve(idx_l, ul, idx_r, ur, T0)
            t_solve += time.perf_counter() - t3
            if np.isfinite(pose.rms_px):
                facing = self._faces_cameras(pose, idx_l, idx_r)
                if best is None or (facing, -pose.rms_px) > (best_facing, -best.rms_px):  # facing fits first
                    best, best_facing = pose, facing
            if self._continuous and best is not None and best_facing and best.rms_px <= s.good_rms_px:
                break
        if best is not None and not best_facing:  # turned inside out: a start in the other minimum
            t3 = time.perf_counter()
            T0 = turned_start(best.T_fit, self.solver.marker_points(np.union1d(idx_l, idx_r)))
            pose = self.solver.solve(idx_l, ul, idx_r, ur, T0)
            t_solve += time.perf_counter() - t3
            if np.isfinite(pose.rms_px) and self._faces_cameras(pose, idx_l, idx_r):
                best, best_facing = pose, True
        timings["init"], timings["solve"] = 1e3 * t_init, 1e3 * t_solve
        if best is None:
            return self._fail(
                "no start pose (need 4 corners in one image or 3 stereo pairs)", cl, cr, t0, timings, match=m
            )
        doubt = ""
        if not best.rms_px <= s.max_rms_px or best.T_left_marker[2, 3] <= 0:
            doubt = f"reprojection RMS {best.rms_px:.2f} px above {s.max_rms_px} px: corners do not fit the marker"
        elif not best_facing:
            doubt = "the fit puts marker corners on the far side of the sleeve (too few corners to tell its tilt)"
        elif (sigma := self._tip_sigma(best, idx_l, idx_r, (ul, ur), _noise_px)) > s.max_tip_sigma_m:
            doubt = (f"the tip is uncertain by {1e3 * sigma:.2f} mm at the corners' noise "
                     f"(too few corners, seen too steeply or beside a highlight, {_TIP_SIGMA_CAUSE}")
        elif (shift := self._single_view_shift(best, idx_l, ul, idx_r, ur, m)) > s.max_single_view_shift_m:
            doubt = f"the fit hinges on corners seen in one view only (the tip moves {1e3 * shift:.1f} mm without them)"
        if doubt:
            if doubt.startswith("reprojection RMS"):  # a corner beside the chain? (_retry_without_chain_ends)
                pols = [None if p is None else p.astype(float) for p in (pl, pr)]
                self._misfits = [*self._misfits[-3:], (cl, cr, pols[0], pols[1])]  # bounded (track_corners alone)
            elif doubt.startswith("the fit hinges") and pl is not None and pr is not None:  # (_retry_partners)
                self._hinged = [*self._hinged[-3:], (cl, cr, pl, pr, best, m)]
            return self._fail(doubt, cl, cr, t0, timings, pose=best, match=m)
        return TrackResult(
            True,
            "",
            best.tip_left,
            best.tip_world,
            best.T_left_marker,
            cl,
            cr,
            best.rms_px,
            1e3 * (time.perf_counter() - t0),
            timings,
            pose=best,
            match=m,
        )
