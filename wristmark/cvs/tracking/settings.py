"""What configures the stereo tracker (cvs.tracking.tracker): its settings and its corner
detectors (the paper's, with the saddle detector as fallback and second try)."""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any, Protocol

from wristmark.cvs.corners.xcorners import DetectorSettings
from wristmark.cvs.marker.decode import CodeReadSettings
from wristmark.cvs.tracking.axis import AxisEvidenceSettings
from wristmark.cvs.tracking.stereo_pose import PoseSettings
from wristmark.models.errors import InputError


class CornerDetector(Protocol):
    """What the tracker needs from a detector (cvs.corners.detector.MarkerCornerDetector):
    ``detect`` gets grey frames (or grey / BGR ones with a ``roi``), ``track`` grey or BGR ones (it
    converts only what it searches); ``previous_roi`` is the box ``track`` searches first, or None;
    ``follow`` centres the next one on corners found otherwise."""

    def detect(self, gray: Any, roi: Any = None) -> Any: ...

    def track(self, gray: Any) -> Any: ...

    def previous_roi(self, shape: tuple[int, ...]) -> Any: ...

    def follow(self, corners: Any) -> None: ...


@dataclass(frozen=True)
class TrackerSettings:
    """min_corners: per camera [-]; min_pairs: stereo pairs needed [-]; max_dy_px: rectified-y
    tolerance of a pair [px] (2.5: under 5 px of motion blur and 1.6 px of defocus a corner beside
    a highlight stripe was 1.2 px off, 2.1 px from its partner; the pose gates judge the fit);
    max_rms_px: largest accepted reprojection RMS [px]; good_rms_px: in
    ROI tracking, an RMS of the fit from the previous pose that ends the search over start poses
    [px]; a cold pair tries every start and keeps the best (local minima of eq. 16 sit near
    0.8-1 px at 0.2 px corner noise, but with 4 nearly collinear corners a wrong pose can fit to
    0.3 px while the true one fits to the noise level); detector:
    'auto' (the paper's detector if installed, else the saddle fallback; when the paper's
    detector finds no marker in a pair, the saddle detector gets one try on the same pair),
    'paper' or 'saddle'; pose: solver settings; axis: the image evidence for the direction of
    z_wm (cvs.tracking.axis); code: reading a coded sleeve's cells (cvs.marker.decode);
    prior_max_move_m [m], prior_max_turn_deg [deg], prior_max_px [px]: the previous pair's pose
    is a prior for the direction only if this pair's fit is within these of it (translation,
    rotation modulo the corner symmetry, the previous pose's corners on this pair's left
    detections: small motion, same corners); strict_direction: never a direction that only the
    default prior (+x) or one-band image evidence gave (cvs.tracking.axis.axis_evidence_strict):
    'direction ambiguous' instead (``wristmark track --strict-direction``);
    max_single_view_shift_m [m]: a fit that uses corners seen in one view only (no stereo
    partner) is refused when the tip moves more than this without them, where at least 3 stereo
    pairs fit on their own (2 pairs determine the pose no better than the fit): few corners on one arc
    of the sleeve leave its axis weakly determined, and one such corner off by a pixel at the
    chain's end tilted the fit 3-5 mm off in the virtual lab (docs/notes/corner-accuracy-on-curved-markers.md);
    min_corner_facing [-]: the least cosine between a used corner's outward sleeve normal and its
    direction to the camera that saw it; a fit below it puts a corner on the far side of the
    sleeve, which hides it (few corners: the arc turned inside out, 3-9 mm off;
    cvs.tracking.sleeve_facing, docs/notes/sleeve-facing.md); magnify [-]: a pair lost for too few
    corners is searched once more in each view's box around its last good corners, enlarged so
    many times (1, the default, disables: at 0.35 x a third of the pairs it recovered in steep
    views were more than 1.5 mm off); the next pair's ROI search stays enlarged while the marker's corners
    are less than magnify_below_px [px] apart (docs/notes/steep-views.md); paper_detector: the
    paper detector's settings (cvs.corners.xcorners.DetectorSettings); corner_sigma_px [px],
    max_tip_sigma_m [m]: a fit whose tip has a standard deviation above max_tip_sigma_m at
    corner_sigma_px of noise on each corner coordinate is refused (three corners of one ring per
    view, small or steeply seen, fix the tilt poorly and can put the tip 2-9 mm off while
    reprojecting to 0.05 px; cvs.tracking.tip_uncertainty, docs/notes/steep-views.md);
    corner_contrast_noise [px x grey levels]: on images (``track``) each used corner's noise is
    corner_sigma_px combined with corner_contrast_noise over the corner's contrast (grey-level
    spread of its HTM window): dim or low-contrast corners fix the tip less well (0: corner_sigma_px
    for all; cvs.tracking.tip_uncertainty.corner_sigmas, docs/notes/highlight-stripe.md);
    clipped_sigma_px [px], clipped_level [grey level], clipped_radius [-]: ... and combined with
    clipped_sigma_px where a pixel of clipped_level or more lies within clipped_radius times the
    chain's spacing of the corner (beside a clipped highlight stripe the HTM fit's linear shading
    is wrong: 0.1-1.6 px off; a pose that rests on such corners alone is refused by
    max_tip_sigma_m; 0 disables); solve_contrast_noise [px x grey levels]: on images the pose
    solve weights each corner by its noise, corner_sigma_px combined with solve_contrast_noise
    over its contrast (7: the relation measured on the path-traced 1080p pairs; 0: unweighted);
    foreshortening_max_facing [-], foreshortening_blur_px [px]: a good, oriented result is
    solved again from its corners less the HTM fit's bias where the sleeve turns away from the
    camera (each used corner facing it at a cosine of at most foreshortening_max_facing, 0.7;
    0: off; the bias drawn at the fit with foreshortening_blur_px of optics blur, in the window
    the detector fitted the corner in; cvs.tracking.foreshortening,
    docs/notes/foreshortened-corners.md: it brings the path-traced tip means down by 1-10 %);
    not where the chains' median spacing is under foreshortening_min_spacing_px [px] (23: at
    half the 1080p scale, 11-18 px, the fits near the silhouette scatter by half a pixel and
    tendon3's half-scale registration turned 0.17 -> 0.25 deg off with it);
    gate_contrast_noise [px x grey levels], max_contrast_tip_sigma_m [m], gate_min_spacing_px
    [px]: a good, oriented result (the pose reported, after the contrast-weighted solve) is
    refused when its tip's standard deviation at each used corner's contrast noise
    (corner_sigma_px combined with gate_contrast_noise over its contrast), multiplied by the fit's
    residual over that noise where the residual is the larger (sqrt(chi^2 / (2 N - 6)) for N used
    corners, at least 1), is above max_contrast_tip_sigma_m: a dark sleeve's 3-4 corners a view
    (0.25-0.35 px of noise: 0.53-0.57 mm off at 0.2 mm of sigma at 0.1 px) and a fit whose
    residual exceeds its corners' noise (3 stereo pairs at 0.31 px: 0.76 mm off) were reported
    under every other gate; the corners' ROIs are kept (docs/notes/highlight-stripe.md). Not
    where the chains' median spacing is under gate_min_spacing_px (23 px: the contrast relation
    was measured on corners 23-80 px apart; below, it overstates the noise: at 0.35 x 1080p, 16 px
    apart, it gave 0.5-0.6 mm of sigma to poses 0.15 mm off, and the loop stopped for a lost
    marker; such corners keep the gate at corner_sigma_px alone), except a fit on chains that
    step over a missed corner, judged there with every corner at corner_sigma_px times its
    residual over it (held-out path-traced 2525/33: 21 px apart, 0.61 px, 0.53 mm off, refused
    at 0.62 mm). gate_contrast_noise 0 or
    max_contrast_tip_sigma_m inf disables (cvs.tracking.arm_set applies the same gate after
    clearing each arm's corners). max_small_fit_tip_sigma_m [m]: one arm's other fits under
    gate_min_spacing_px are judged the same way (every corner at corner_sigma_px times the fit's
    residual over it) against this bound, and report that sigma (inf: neither): in the loop at
    0.25 and 0.35 x 1080p, 5800 such fits of four arms stayed under 0.95 mm, where two wrong ones
    (single_tendon at 0.25 x, 3 corners 9 px apart at 0.37-0.67 px, 17-18 mm off) gave 2.8 and
    5.2 mm (docs/notes/steep-views.md). edge_sigma_px [px], edge_max_rms_px [px], edge_min_samples,
    edge_min_spacing_px [px]: a
    good, oriented result is solved again from its corners and the centre lines of the print's
    dark bars (cvs.tracking.print_edges: the checker patches, and a coded sleeve's code cells
    where its roll is known), each bar sample at edge_sigma_px (0.5: measured on the path-traced
    sets; 0 disables), where at least edge_min_samples bar samples are found and both corners and
    bars then reproject within edge_max_rms_px RMS, and the chains' median spacing is
    edge_min_spacing_px or more (measured on 1080p corners 23-80 px apart; at 0.35 x 1080p a
    code band is 6 px tall and the search crosses it); a sleeve seen side-on shows one arc of
    corners at z = 0, and the bars up to +-5 mm fix its tilt (docs/notes/highlight-stripe.md).
    edge_blur_fit_px [px]: a bar edge whose profile rises too slowly for the largest gradient (a
    blurred sleeve) is measured by a blurred step fitted to its profile's unclipped levels over
    +-edge_blur_fit_px, where its white level is seen under the clip (0: off; print_edges.measure_edges,
    bench/bar_edges.py; docs/notes/print-bars.md, "Blurred bars"). Not in the two-pair path, which
    measures the bars of every roll hypothesis (the fit made it ~6 x slower).
    edge_blur_max_sigma_px [px]: the widest blur that fit may find: a sharp step into the white
    square's shading ramp (near a highlight) fits as a wide blur placed in the ramp (path-traced
    1010/41: sigma ~2.8 px, 1.7 px off; docs/notes/print-bars.md, "The fit's widest blur").
    eroded_sizes [px], eroded_min_clipped_px: a pair lost for too few corners or without a start
    pose after every other search (the reduced one below included), where each view has at least
    eroded_min_clipped_px pixels at clipped_level or more, is searched again in each view eroded by
    a disc of each size in turn (white squares exposed at several times full scale and blurred over
    the corners: a sleeve close to the lens), its corners then fitted on the views themselves by the
    HTM model with the clipped pixels censored (cvs.corners.clipped_fit); the same pose gates, and
    the tip's standard deviation with every corner at clipped_sigma_px within max_tip_sigma_m
    (empty: off; MarkerTracker._retry_eroded). bars_gate: a whole-frame fit refused by the tip-sigma
    gate (max_tip_sigma_m) is oriented and refined with the print's bars as above, and kept where
    the tip's sigma from the corners and the bars together is within max_tip_sigma_m at the gate's
    corner noise and within max_contrast_tip_sigma_m at the contrast noise: bars up to +-5 mm fix
    the tilt that 3-4 corners of a steeply seen sleeve leave open (needs edge_sigma_px > 0;
    MarkerTracker._retry_with_bars). partner_max_px [px]: a whole-frame fit refused because it
    hinges on corners seen in one view only (max_single_view_shift_m) has each such corner looked
    for in the other view where that fit puts it, by the HTM fit (censored where its window clips),
    kept within partner_max_px of that place, and the pair solved again with those partners under
    every gate (0: off; MarkerTracker._retry_partners). reduced_scales [-]: a pair still lost for
    too few corners, no start pose or a fit on too few corners is searched once more (before the
    eroded search: the cheaper first) in each whole view reduced by each factor in turn (area
    averaging; a sleeve close to the lens or out of focus, its corners blurred over several pixels,
    fails the X-corner test at full and half scale), its corners then fitted on the views themselves
    as in the eroded search, under the same gates; the first factor that passes is kept (empty: off;
    MarkerTracker._retry_reduced). reduced_sigma_px [px]: the noise of each corner of the reduced
    search's fits (its place from the reduced view or, beside clipped pixels, fitted again with them
    censored): a reduced fit that passes the tip-sigma gates (max_tip_sigma_m) only with every
    corner at this noise is the pair's last resort, used where every later search leaves it lost
    (MarkerTracker._last_resort), and every reduced result reports its sigma at it; measured
    0.24-0.35 px RMS per coordinate on the held-out path-traced sets 2020-2828, beside clipped
    pixels or not, where the contrast relation says 0.12 px (bench/pbr_tracking.py, corner_errors:
    the gates, counting those beside clipped pixels at clipped_sigma_px, refused steep references
    0.13-0.30 mm off at 1.08-1.34 mm; docs/notes/highlight-stripe.md); 0: off (the results report
    each corner beside a clipped pixel clipped_sigma_px noisier). wide_sigma_px [px]: a fit the
    contrast gate refused whose
    corners lie further apart than the detector's HTM window serves (its Gaussian weights, 0.12
    times the distance to the nearest other corner, stop at 4 px: a corner more than ~33 px from
    the next, close to the lens and blurred by defocus, is fitted from its noisy centre alone) has
    its matched corners fitted again with weights up to wide_sigma_px in a window of 1.25 times
    that, at the fit's own edge directions, and is solved, oriented and judged again under every
    gate (4 or less: off; MarkerTracker._retry_wide_windows). wide_residual_factor [-]: a good
    result that the contrast gate found reprojecting more than this times its corners' contrast
    noise (the gate's residual factor) has its corners fitted again in wide windows too, and the
    new result is kept where it passes every gate and reports a smaller tip sigma (0: off;
    MarkerTracker._wide_if_surer; 2: on the path-traced sets 2020-2727 it took 9 tips 0.01-0.19
    mm nearer the truth and 2 others 0.07-0.09 mm further off; 1.5 changed 8 more pairs by
    -0.05 to +0.03 mm). two_pairs_min_bars, two_pairs_margin
    [-]: a coded sleeve still lost for too few corners or without a start pose, whose views each
    show a chain of only two corners (seen steeply, the next corners fail the X-corner test), is
    put on the chord those two stereo pairs fix, turned to the sleeve axis their edges show, in
    every roll hypothesis, each scored by the print's bar samples found there (code cells
    included); the best is kept where it has two_pairs_min_bars samples or more, two_pairs_margin
    times as many as any other hypothesis, corners and bars within edge_max_rms_px, its code read
    with the same roll, and the tip's sigma from corners and bars within the bars gate's bounds
    (0 min bars: off; needs edge_sigma_px > 0; cvs.tracking.two_pairs, MarkerTracker._retry_two_pairs).
    other_view_cl_scale [-], other_view_depths_m [m]: a pair lost for too few corners whose chains
    stepping over a missed corner give one view a chain and the other none has the other view
    searched once more in the box where that chain's corners can appear (their rays between the
    two depths, cvs.tracking.epipolar_box, grown by two spacings), its candidates down to
    other_view_cl_scale times the CL threshold, stepping over missed corners too, under every gate
    (0: off; a highlight stripe's edge lowered a plain corner's normalised CL to 0.057 against the
    threshold's 0.06, path-traced 2323/57; docs/notes/highlight-stripe.md)."""

    min_corners: int = 3
    min_pairs: int = 2
    max_dy_px: float = 2.5
    max_rms_px: float = 0.75
    good_rms_px: float = 0.4
    detector: str = "auto"
    pose: PoseSettings = field(default_factory=PoseSettings)
    axis: AxisEvidenceSettings = field(default_factory=AxisEvidenceSettings)
    code: CodeReadSettings = field(default_factory=CodeReadSettings)
    prior_max_move_m: float = 0.003
    prior_max_turn_deg: float = 15.0
    prior_max_px: float = 6.0
    strict_direction: bool = False
    max_single_view_shift_m: float = 0.001
    min_corner_facing: float = 0.0
    magnify: float = 1.0
    corner_sigma_px: float = 0.1
    max_tip_sigma_m: float = 0.001
    corner_contrast_noise: float = 0.0
    solve_contrast_noise: float = 7.0
    foreshortening_max_facing: float = 0.7
    foreshortening_blur_px: float = 0.8
    foreshortening_min_spacing_px: float = 23.0
    clipped_sigma_px: float = 1.0
    clipped_level: int = 250
    clipped_radius: float = 0.25
    gate_contrast_noise: float = 7.0
    max_contrast_tip_sigma_m: float = 0.5e-3
    gate_min_spacing_px: float = 23.0
    max_small_fit_tip_sigma_m: float = 1.5e-3
    paper_detector: DetectorSettings = field(default_factory=DetectorSettings)
    magnify_below_px: float = 20.0
    edge_sigma_px: float = 0.5
    edge_max_rms_px: float = 0.5
    edge_min_samples: int = 8
    edge_min_spacing_px: float = 23.0
    edge_blur_fit_px: float = 7.5
    edge_blur_max_sigma_px: float = 2.5
    eroded_sizes: tuple[int, ...] = (3, 5, 7, 9, 11)
    eroded_min_clipped_px: int = 200
    bars_gate: bool = True
    partner_max_px: float = 1.0
    other_view_cl_scale: float = 0.5
    other_view_depths_m: tuple[float, float] = (0.015, 0.3)
    reduced_scales: tuple[int, ...] = (2, 3, 4)
    reduced_sigma_px: float = 0.5
    wide_sigma_px: float = 8.0
    wide_residual_factor: float = 2.0
    two_pairs_min_bars: int = 24
    two_pairs_margin: float = 1.4

    def __post_init__(self) -> None:
        sizes = tuple(self.eroded_sizes)
        if any(not isinstance(k, int) or isinstance(k, bool) or k < 2 for k in sizes):
            raise InputError(f"TrackerSettings.eroded_sizes must be integers >= 2 [px] (empty: off), got {sizes}")
        object.__setattr__(self, "eroded_sizes", sizes)  # a list given stays hashable, like the default
        scales = tuple(self.reduced_scales)
        if any(not isinstance(k, int) or isinstance(k, bool) or k < 2 for k in scales):
            raise InputError(f"TrackerSettings.reduced_scales must be integers >= 2 (empty: off), got {scales}")
        object.__setattr__(self, "reduced_scales", scales)
        if not float(self.reduced_sigma_px) >= 0:  # NaN too
            raise InputError(f"TrackerSettings.reduced_sigma_px must be >= 0 [px] (0: the clipped-pixel model), "
                             f"got {self.reduced_sigma_px}")
        if not float(self.wide_sigma_px) >= 0:  # NaN too
            raise InputError(f"TrackerSettings.wide_sigma_px must be >= 0 [px] (4 or less: off), "
                             f"got {self.wide_sigma_px}")
        if not (float(self.wide_residual_factor) == 0 or float(self.wide_residual_factor) >= 1):  # NaN too
            raise InputError(f"TrackerSettings.wide_residual_factor must be 0 (off) or >= 1, "
                             f"got {self.wide_residual_factor}")
        if int(self.eroded_min_clipped_px) < 0:
            raise InputError(f"TrackerSettings.eroded_min_clipped_px must be >= 0, got {self.eroded_min_clipped_px}")
        if not float(self.max_dy_px) > 0:  # NaN too
            raise InputError(f"TrackerSettings.max_dy_px must be > 0 [px], got {self.max_dy_px}")
        for name in ("gate_contrast_noise", "gate_min_spacing_px"):
            v = float(getattr(self, name))
            if not v >= 0:  # NaN too
                raise InputError(f"TrackerSettings.{name} must be >= 0, got {v}")
        if not float(self.edge_sigma_px) >= 0:
            raise InputError(f"TrackerSettings.edge_sigma_px must be >= 0 (0: off), got {self.edge_sigma_px}")
        if not float(self.edge_max_rms_px) > 0:
            raise InputError(f"TrackerSettings.edge_max_rms_px must be > 0, got {self.edge_max_rms_px}")
        if not float(self.edge_min_spacing_px) >= 0:
            raise InputError(f"TrackerSettings.edge_min_spacing_px must be >= 0, got {self.edge_min_spacing_px}")
        if not float(self.partner_max_px) >= 0:
            raise InputError(f"TrackerSettings.partner_max_px must be >= 0 [px] (0: off), got {self.partner_max_px}")
        if not 0 <= float(self.edge_blur_fit_px) < float("inf"):
            raise InputError(f"TrackerSettings.edge_blur_fit_px must be >= 0 (0: off), got {self.edge_blur_fit_px}")
        if not 0 < float(self.edge_blur_max_sigma_px) < float("inf"):
            raise InputError(f"TrackerSettings.edge_blur_max_sigma_px must be > 0, got {self.edge_blur_max_sigma_px}")
        if int(self.edge_min_samples) < 1:
            raise InputError(f"TrackerSettings.edge_min_samples must be >= 1, got {self.edge_min_samples}")
        if not 0 <= float(self.foreshortening_max_facing) <= 1:  # NaN too
            raise InputError(f"TrackerSettings.foreshortening_max_facing must be in [0, 1] (0: off), "
                             f"got {self.foreshortening_max_facing}")
        if not 0 <= float(self.foreshortening_min_spacing_px) < float("inf"):
            raise InputError(f"TrackerSettings.foreshortening_min_spacing_px must be >= 0 [px], "
                             f"got {self.foreshortening_min_spacing_px}")
        if not 0 <= float(self.foreshortening_blur_px) < float("inf"):
            raise InputError(f"TrackerSettings.foreshortening_blur_px must be >= 0 [px], "
                             f"got {self.foreshortening_blur_px}")
        if not float(self.max_small_fit_tip_sigma_m) > 0:
            raise InputError(f"TrackerSettings.max_small_fit_tip_sigma_m must be > 0 (inf: off), "
                             f"got {self.max_small_fit_tip_sigma_m}")
        if not float(self.max_contrast_tip_sigma_m) > 0:
            raise InputError(f"TrackerSettings.max_contrast_tip_sigma_m must be > 0 (inf: off), "
                             f"got {self.max_contrast_tip_sigma_m}")
        if not 0 <= float(self.other_view_cl_scale) <= 1:  # NaN too
            raise InputError(f"TrackerSettings.other_view_cl_scale must be in [0, 1] (0: off), "
                             f"got {self.other_view_cl_scale}")
        near, far = (float(v) for v in self.other_view_depths_m)
        if not 0 < near < far < float("inf"):
            raise InputError(f"TrackerSettings.other_view_depths_m must be two depths 0 < near < far [m], "
                             f"got {list(self.other_view_depths_m)}")
        if int(self.two_pairs_min_bars) < 0:
            raise InputError(f"TrackerSettings.two_pairs_min_bars must be >= 0 (0: off), got {self.two_pairs_min_bars}")
        if not float(self.two_pairs_margin) >= 1:  # NaN too
            raise InputError(f"TrackerSettings.two_pairs_margin must be >= 1, got {self.two_pairs_margin}")


def make_detector(kind: str, settings: DetectorSettings | None = None) -> CornerDetector:
    """A corner detector of ``kind`` ('auto', 'paper', 'saddle'; InputError for another);
    ``settings``: the paper detector's (default DetectorSettings())."""
    if kind not in ("auto", "paper", "saddle"):
        raise InputError(f"unknown detector '{kind}' (valid: auto, paper, saddle)")
    if kind in ("auto", "paper"):
        try:
            mod = importlib.import_module("wristmark.cvs.corners.detector")
            det: CornerDetector = mod.MarkerCornerDetector(settings)
            return det
        except ImportError as e:
            if kind == "paper":
                raise InputError("the paper's detector (cvs.corners.detector) is not installed") from e
    from wristmark.cvs.corners.saddle import SaddleCornerDetector

    return SaddleCornerDetector()
