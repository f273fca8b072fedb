"""Which way the wrist marker points: image evidence for the direction of z_wm (distal).

The checkered sleeve is invariant under a half turn about x_wm (corner i -> -i, z -> -z, and the
two rows swap colours), so the corners alone cannot tell the tip's side of the marker from the
arm's side: both poses reproject the corners exactly. The image can: the arm's body continues
on the proximal side (-z) right behind the sleeve and far beyond it, while on the distal side
only the (narrower) tool reaches the tip at ``tip_offset`` and nothing of the arm lies beyond.

``axis_evidence`` measures, in both images, how much "object" there is on each side of the
sleeve along the marker's axis: the grey-level contrast between points on the axis's flanks
(inside the silhouette of an arm about as wide as the sleeve, outside that of a thin tool) and
points well outside the silhouette, in two bands: just behind the sleeve's ends and beyond
the tip's distance. It returns a score in [-1, 1]: > 0 supports the pose's z_wm as distal,
< 0 the half-turned pose, ~0 no evidence (the caller then falls back to a prior).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.cvs.marker.cells import sample_camera_points
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]


@dataclass(frozen=True)
class AxisEvidenceSettings:
    """Where the evidence is sampled, in marker radii r along and across the axis [-].

    near: distances beyond the sleeve's ends (in r); far: distances beyond the tip's distance
    (in r); offsets: lateral offsets searched for a silhouette edge (in r: an arm about as wide
    as the sleeve, not a thin tool); step: half the width of the grey-level step (in r);
    max_reach: a band is skipped when a sleeve end (its face or its rim) hides it beyond this
    (in r); min_samples: least valid samples per offset; decide: least |score| that decides;
    margin: a |score| from decide to decide + margin is marginal and decides only where the
    tracker's default prior agrees (else the direction is ambiguous: a path-traced pair's lit
    tool gave 0.145 the wrong way, docs/notes/highlight-stripe.md); min_edge: least edge
    strength of the stronger side for a band to count [grey levels];
    decide_strict: least |far score| that decides in axis_evidence_strict; veto_strict: a near
    score this far the other way vetoes it; arm_offsets: the lateral offsets (in r) of the
    arm-width check that must back decisive evidence by ``decide`` (else it is only marginal) and
    settles marginal evidence against the default prior (only a body about
    as wide as the sleeve: a thin tool with the shadow ring that a light beside the lenses casts
    around it reached 0.5-0.6 r on path-traced pairs, the arm's body and its ring about 1.0 r;
    MarkerTracker._orient; empty: no such check); min_band_edge: a band (camera, near or far) in
    which neither side's edge strength exceeds this counts for nothing in axis_evidence [grey
    levels] (0: every band counts); arm_min_edge: min_band_edge of the arm-width check (behind a
    body that bends away, the far band shows 2-9 grey levels on both sides, and the score's
    normalisation would make two noise levels a full vote).
    """

    near: tuple[float, ...] = (0.2, 0.35, 0.5, 0.65, 0.8)
    far: tuple[float, ...] = (1.0, 1.3, 1.6, 1.9, 2.2)
    max_reach: float = 2.5
    offsets: tuple[float, ...] = (0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.1)
    step: float = 0.06
    min_samples: int = 4
    decide: float = 0.1
    margin: float = 0.1
    decide_strict: float = 0.3
    veto_strict: float = 0.5
    min_edge: float = 30.0
    arm_offsets: tuple[float, ...] = (0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.1)
    min_band_edge: float = 0.0
    arm_min_edge: float = 10.0

    def __post_init__(self) -> None:
        offsets = tuple(float(o) for o in self.arm_offsets)
        if not all(np.isfinite(o) and o > 0 for o in offsets):
            raise InputError(f"AxisEvidenceSettings.arm_offsets must be > 0 [marker radii] (empty: off), got {offsets}")
        object.__setattr__(self, "arm_offsets", offsets)  # a list given stays hashable, like the default
        for name in ("min_band_edge", "arm_min_edge"):
            v = float(getattr(self, name))
            if not v >= 0:  # NaN too
                raise InputError(f"AxisEvidenceSettings.{name} must be >= 0 [grey levels], got {v}")


def _side_edges(img: NDArray[np.uint8], cam: Camera, T_cam_marker: Array, zs: Array, r: float,
                s: AxisEvidenceSettings) -> float:
    """Strength of silhouette edges running along the axis at axis positions zs [m]: for each
    flank and lateral offset in ``s.offsets`` (in r), the mean over zs of the grey-level step
    across the axis (signed, so only an edge parallel to the axis adds up); the strongest
    offset per flank, summed over both flanks [grey levels]. NaN: too few samples in view."""
    R, t = T_cam_marker[:3, :3], T_cam_marker[:3, 3]
    ez = R[:, 2]
    P = t[None, :] + zs[:, None] * ez[None, :]  # axis points in the camera frame
    lat = np.cross(ez[None, :], P)  # across the axis, perpendicular to the line of sight
    n = np.linalg.norm(lat, axis=1, keepdims=True)
    if np.any(n < 1e-12) or np.any(P[:, 2] <= 0):
        return float("nan")
    lat = lat / n
    offs = np.asarray(s.offsets, float)
    total = 0.0
    # all samples at once: (flank, out/in, offset, z) -> one projection and sampling pass
    sides = np.array([1.0, -1.0])[:, None, None, None]
    io = np.array([1.0, -1.0])[None, :, None, None]
    k = sides * (offs[None, None, :, None] + io * s.step) * r  # lateral distance (signed by flank)
    X = P[None, None, None] + k[..., None] * lat[None, None, None]
    g = sample_camera_points(img, X.reshape(-1, 3), cam.K, cam.dist).reshape(2, 2, offs.size, zs.size)
    for f in range(2):
        d = g[f, 0] - g[f, 1]
        valid = np.isfinite(d).sum(axis=1)
        if valid.min() < s.min_samples:
            return float("nan")
        total += float(np.max(np.abs(np.nanmean(d, axis=1))))
    return total


def axis_bands(images: tuple[NDArray[np.uint8], NDArray[np.uint8]], camera: StereoCamera, marker: MarkerModel,
               T_left_marker: Array, settings: AxisEvidenceSettings | None = None, left_only: bool = False) -> Array:
    """Edge strengths [grey levels] (camera, band, side): cameras left, right; bands near (just
    beyond the sleeve's ends) and far (beyond the tip's distance); sides distal, proximal (as
    posed). NaN where a band is hidden or out of view (and for the right camera if left_only)."""
    s = settings or AxisEvidenceSettings()
    z_lo, z_hi = marker.z_extent
    r, h, tip = marker.radius, max(-z_lo, z_hi), float(marker.tip()[2])
    T_rl = np.eye(4)
    T_rl[:3, :3], T_rl[:3, 3] = camera.R, camera.T
    poses = (np.asarray(T_left_marker, float), T_rl @ np.asarray(T_left_marker, float))
    out = np.full((2, 2, 2), np.nan)
    for c, (img, cam, T) in enumerate(zip(images[: 1 if left_only else 2], (camera.left, camera.right), poses)):
        for b, (base, steps) in enumerate(((h, s.near), (max(tip, h), s.far))):
            for i, side in enumerate((1.0, -1.0)):  # distal, proximal (as posed)
                k = np.asarray(steps, float) + _face_reach(T, side, base, s)
                if k[0] <= s.max_reach:
                    out[c, b, i] = _side_edges(img, cam, T, side * (base + r * k), r, s)
    return out


def axis_evidence(images: tuple[NDArray[np.uint8], NDArray[np.uint8]], camera: StereoCamera, marker: MarkerModel,
                  T_left_marker: Array, settings: AxisEvidenceSettings | None = None, left_only: bool = False) -> float:
    """Score in [-1, 1] that z_wm of ``T_left_marker`` (pose of {wm} in {ll}) points distally:
    > 0 the arm's body lies on its -z side, < 0 on its +z side (the half-turned pose is the
    right one), 0 when the images say nothing (marker seen end-on, out of view, no contrast):
    the mean over cameras (``left_only``: the left one) and both bands of (proximal - distal) /
    (proximal + distal), over the bands where either side's edge exceeds
    ``settings.min_band_edge``. A distal
    tool as wide as the arm, with no body behind the sleeve, fools it (axis_evidence_strict)."""
    s = settings or AxisEvidenceSettings()
    e = axis_bands(images, camera, marker, T_left_marker, s, left_only)
    with np.errstate(invalid="ignore", divide="ignore"):
        score = (e[:, :, 1] - e[:, :, 0]) / (e[:, :, 1] + e[:, :, 0])
    ok = np.isfinite(score) & (e[:, :, 1] + e[:, :, 0] > 1e-9) & (np.fmax(e[:, :, 0], e[:, :, 1]) > s.min_band_edge)
    return float(np.mean(score[ok])) if ok.any() else 0.0


def axis_evidence_strict(images: tuple[NDArray[np.uint8], NDArray[np.uint8]], camera: StereoCamera,
                         marker: MarkerModel, T_left_marker: Array, settings: AxisEvidenceSettings | None = None,
                         left_only: bool = False) -> float:
    """Score in [-1, 1] that z_wm of ``T_left_marker`` (pose of {wm} in {ll}) points distally:
    > 0 the arm's body lies on its -z side, < 0 on its +z side (the half-turned pose is the
    right one), 0 when the images say nothing (marker seen end-on, out of view, no contrast).

    The far band decides, the near band may only veto: beyond the tip's distance there is
    nothing distally and the body proximally (if it is in view), while just beyond the sleeve's
    ends a distal tool as wide as the arm looks like a body (so without a body behind the sleeve
    the near band alone points the wrong way). Per band the mean score (proximal - distal) /
    (proximal + distal) over the cameras whose stronger side shows at least ``min_edge`` grey
    levels (the cameras must agree on the far band). The result is the far score if it reaches
    ``decide_strict`` and the near score (if any) is not beyond ``veto_strict`` the other way,
    else 0 (no decision: a strict tracker then reports the direction as ambiguous)."""
    s = settings or AxisEvidenceSettings()
    e = axis_bands(images, camera, marker, T_left_marker, s, left_only)
    with np.errstate(invalid="ignore", divide="ignore"):
        score = (e[:, :, 1] - e[:, :, 0]) / (e[:, :, 1] + e[:, :, 0])  # (camera, band)
    strong = np.fmax(e[:, :, 0], e[:, :, 1]) >= s.min_edge
    v = score[:, 1][np.isfinite(score[:, 1]) & strong[:, 1]]
    if v.size == 0 or (v.size == 2 and v[0] * v[1] <= 0):
        return 0.0
    far = float(np.mean(v))
    u = score[:, 0][np.isfinite(score[:, 0]) & strong[:, 0]]
    if abs(far) < s.decide_strict or (u.size and float(np.mean(u)) * np.sign(far) <= -s.veto_strict):
        return 0.0
    return far


def _face_reach(T_cam_marker: Array, side: float, z_face: float, s: AxisEvidenceSettings) -> float:
    """How far (in marker radii, along the axis) the sleeve's end at z = side * z_face covers the
    flank samples beyond it in the image: sqrt(1 - o^2) / tan(alpha) for the innermost flank
    offset o and the angle alpha between the line of sight and the axis. The rim projects to an
    ellipse about the end's centre, so this holds whichever way the face turns: a face turned
    towards the camera shows itself there, one turned away the near half of its rim (counted as
    object on that side before: seed 202 pair 18 of bench/pbr_tracking.py, the half turn)."""
    ez, t = T_cam_marker[:3, 2], T_cam_marker[:3, 3]
    centre = t + side * z_face * ez
    to_cam = -centre / np.linalg.norm(centre)
    c = abs(float(side * ez @ to_cam))  # > 0 turned towards the camera, < 0 away: the same reach
    if c <= 1e-6:
        return 0.0
    tan_a = np.sqrt(max(1.0 - c * c, 0.0)) / c
    o = min(s.offsets)
    return float(np.sqrt(1.0 - o * o) / max(tan_a, 1e-6))
