"""Settings and results of the paper's X-corner detector (cvs.corners.detector).

Image frame: raw (distorted) pixels, x right, y down, pixel (0, 0) is the centre of the top-left
pixel; angles in radians measured from +x towards +y. Grey levels are scaled to [0, 1]. ROIs are
(x, y, w, h) [px] as in cvs.corners.saddle.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError

Array = NDArray[np.float64]
IntArray = NDArray[np.int_]
Roi = tuple[int, int, int, int]


@dataclass(frozen=True)
class DetectorSettings:
    """Settings of the paper's detector (pixels of the processed image, grey levels in [0, 1]).

    epsilon: eq. 6 weight [px]; smooth_sigma: Gaussian smoothing before the Sobel derivatives
    [px]; nms_size: NMS neighbourhood [px]; cl_threshold: least normalised CL [-];
    contrast_floor: least grey range used to normalise CL [-]; half_window: the 10x10
    neighbourhood as a centred (2 h + 1)^2 window [px]; cc_min: least |CC| of an X-corner [-];
    template_scale: tanh edge width of the HTM [px]; quad_size: side of the quadric patch [px];
    refine: HTM least-squares refinement after eq. 10; refine_radius: its window half-size [px],
    at least; refine_window_sigmas: ... or this many times the fit's Gaussian weights' sigma
    where larger (1.5, the default: 11 x 11 for corners 22-28 px apart, 13 x 13 above, closer on
    defocused path-traced pairs; 0: refine_radius for all, as before stop 69:
    cvs.corners.subpixel.htm_radius, docs/notes/highlight-stripe.md) [-];
    max_step_px: search distance for the second marker corner [px]; stop_ratio: chain search
    limit in units of the last spacing [-]; edge_tol_deg: angle between a step and the found
    corner's edge [deg]; cross_edge_tol_deg: angle between consecutive chain corners' edges across
    the chain (the column boundaries of the marker, nearly parallel; texture's X-like crossings
    along a line are not) [deg]; chain_polarity: how the chain's corners alternate, "along" (each
    corner's polarity relative to the chain's direction, cvs.corners.chain.along_polarity) or
    "image" (the X-corner test's own, which flips where a steeply seen sleeve's edges both lean
    ~45 deg: bench/tracker_walks.py --compare chain_polarity); contrast_ratio: least grey range
    of the next chain corner relative to the current one [-]; min_corners: shortest chain [-];
    max_seeds: first corners tried [-];
    seed_candidates: strongest candidates that may be a first corner (on rendered frames the
    marker's first corner ranks below 40) [-]; max_candidates: candidates kept [-];
    roi_margin_px: ROI margin around the previous corners, plus their largest spacing [px];
    coarse_scale: downscale of the cold whole-frame search (1: off) [-]; coarse_min_width:
    narrowest image that gets it [px]; max_gaps: missed corners the chain of
    ``MarkerCornerDetector.retry_with_gaps`` may step over (the tracker's last try on a pair it
    could not track: a specular highlight over the corner the camera sees best; 0: no such try;
    cvs.corners.chain, docs/notes/highlight-stripe.md) [-]; gap_ratio: the farthest such step in
    units of the last spacing [-].
    """

    epsilon: float = 2.0
    smooth_sigma: float = 1.5
    nms_size: int = 5
    cl_threshold: float = 0.06
    contrast_floor: float = 0.2
    half_window: int = 5
    cc_min: float = 0.8
    template_scale: float = 1.0
    quad_size: int = 7
    refine: bool = True
    refine_radius: int = 4
    refine_window_sigmas: float = 1.5
    max_step_px: float = 120.0
    stop_ratio: float = 2.0
    edge_tol_deg: float = 20.0
    cross_edge_tol_deg: float = 30.0
    chain_polarity: str = "along"
    contrast_ratio: float = 0.4
    min_corners: int = 3
    max_seeds: int = 40
    seed_candidates: int = 300
    max_candidates: int = 3000
    roi_margin_px: int = 25
    coarse_scale: int = 2
    coarse_min_width: int = 1000
    max_gaps: int = 1
    gap_ratio: float = 3.6

    def __post_init__(self) -> None:
        if self.chain_polarity not in ("along", "image"):
            raise InputError(f"chain_polarity must be 'along' or 'image', got '{self.chain_polarity}'")
        if not float(self.refine_window_sigmas) >= 0:  # NaN too
            raise InputError(f"refine_window_sigmas must be >= 0 (0: refine_radius for every corner), "
                             f"got {self.refine_window_sigmas}")


def scaled_settings(s: DetectorSettings, k: int) -> DetectorSettings:
    """Settings for an image k times smaller (distances shrink, windows stay, no refinement)."""
    return replace(s, smooth_sigma=max(s.smooth_sigma / k, 1.0), max_step_px=s.max_step_px / k, refine=False)


@dataclass(frozen=True)
class XCorners:
    """X-corners of one image (raw pixels of the full image).

    corners (N, 2): sub-pixel positions [px] (HTM-refined when enabled); corners_quadric (N, 2):
    eq. 10 positions [px]; polarity (N,) +-1; cc (N,): |CC| of eq. 8 [-]; cl (N,): normalised CL
    [-]; edges (N, 2): angles of edge a (near vertical, pointing down) and edge b (pointing right)
    [rad].
    """

    corners: Array
    corners_quadric: Array
    polarity: IntArray
    cc: Array
    cl: Array
    edges: Array

    @staticmethod
    def empty() -> XCorners:
        """No corner."""
        z = np.zeros((0, 2))
        return XCorners(z, z.copy(), np.zeros(0, int), np.zeros(0), np.zeros(0), z.copy())

    def take(self, idx: IntArray | list[int]) -> XCorners:
        """Subset / reordering by row indices."""
        i = np.asarray(idx, int)
        return XCorners(
            self.corners[i], self.corners_quadric[i], self.polarity[i], self.cc[i], self.cl[i], self.edges[i]
        )


@dataclass(frozen=True)
class CornerChain(XCorners):
    """The marker's corner chain (same fields as XCorners, rows ordered along the chain) plus
    roi: the searched box (x, y, w, h) [px] or None for the whole frame; time_ms: detection time
    [ms]; extras: times of sub-steps [ms], summed over the searched images ("gray_ms": crop and
    grey conversion, "candidates_ms": smoothing, CL and NMS, "chain_ms": X-corner tests and the
    chain search, "subpixel_ms": eq. 10 and the HTM fit; "coarse_ms": the whole 2x smaller cold
    search)."""

    roi: Roi | None = None
    time_ms: float = 0.0
    extras: dict[str, float] = field(default_factory=dict)
