"""Independent checker of the stereo dataset contract of docs/design.md ("Stereo dataset format").

Written from docs/design.md alone: it uses only numpy, scipy, opencv, yaml and json, never the project's
packages, so that it checks our renderer (``wristmark render``) against the contract rather than itself.

Checks (tolerances below): the files; calib.yaml keys and shapes (K, dist, proper R, T in metres, optional
world_T_left); marker.yaml; image sizes; truth.json structure and indices; tip = t + R [0, 0, tip_offset];
every corner uv = cv2.projectPoints of the posed corner (right eye through R, T); cos_view recomputed; the
pixels agree with truth (cv2.cornerSubPix from 1-1.5 px away, and a fit of the ideal pattern); the patch
colours follow the pattern. It also scores ``wristmark track --json`` output against truth.json.

Frames and units (docs/design.md): SI (metres, radians); {ll} is the left camera frame (OpenCV: x right,
y down, z along the optical axis); ``X_right = R X_left + T``; pixel (0, 0) is the centre of the top-left
pixel; truth ``R, t`` is the pose of the marker frame {wm} in {ll}; corner i of the marker is
``[r cos(i beta), r sin(i beta), 0]`` in {wm}; ``uv`` are raw (distorted) pixels.

Command line: ``python -m wristmark_testing.independent_dataset_check DIR`` prints a JSON summary and exits 1 when
the dataset violates the contract.
"""

from __future__ import annotations

import json
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from scipy.optimize import minimize

#: Tolerances (documented in the summary).
PROJ_TOL_PX = 1e-6  # truth uv vs cv2.projectPoints of the posed corner [px]
COS_TOL = 1e-9  # truth cos_view vs recomputed cosine [-]
TIP_TOL_M = 1e-9  # truth tip vs t + R [0, 0, tip_offset] [m]
ROT_TOL = 1e-6  # orthonormality of rotation matrices [-]
SUBPIX_COS_MIN = 0.3  # corners used for the cornerSubPix check: cos_view above this
SUBPIX_MIN_HALF = 4  # smallest cornerSubPix half-window [px]: corners closer to other features are skipped
SUBPIX_MAX_HALF = 10  # largest cornerSubPix half-window [px]
# cornerSubPix on the curved, shaded marker is biased by the row boundary's curvature and by the shading
# difference between the patches (measured: noise-free renders 0.15-0.26 px RMS; realistic sets of both
# renderers 0.19-0.26 px RMS, up to 0.70 px): a loose check that still catches a half-pixel error. The model
# fit (ideal pattern + smooth shading fields) is the tight one: noise-free renders 0.011-0.022 px RMS,
# realistic sets 0.03-0.07 px RMS, up to 0.27 px (grazing corners), mean offset below 0.011 px.
SUBPIX_RMS_TOL_PX = 0.35  # RMS of cornerSubPix result vs truth uv [px]
SUBPIX_MAX_TOL_PX = 0.8  # largest single cornerSubPix error [px]
MODEL_MIN_HALF = 4  # smallest model-fit half-window [px]
MODEL_MAX_HALF = 12  # largest model-fit half-window [px]
MODEL_RMS_TOL_PX = 0.1  # RMS of the model-fit offset of the image pattern vs truth [px]
MODEL_MAX_TOL_PX = 0.35  # largest single model-fit offset [px]
MODEL_BIAS_TOL_PX = 0.03  # length of the mean model-fit offset over the dataset [px]
PATCH_COS_MIN = 0.3  # patch centres used for the colour check: cos_view above this
PATCH_MIN_CONTRAST = 1.25  # bright / dark grey ratio required between paired patches [-]

UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-12)  # round trip < 1e-10 px
PAIR_RE = re.compile(r"^pair_(\d{2,})_(left|right)\.png$")
DIST_LENGTHS = (4, 5, 8, 12, 14)


@dataclass
class Camera:
    """One calibrated eye: intrinsics K [px], distortion (OpenCV order) and its pose w.r.t. {ll}.

    ``R, T`` map left-camera coordinates to this camera: ``X_cam = R X_left + T`` [m]
    (identity / zero for the left camera).
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    T: np.ndarray

    @property
    def centre_left(self) -> np.ndarray:
        """Optical centre of this camera in {ll} [m]."""
        return -self.R.T @ self.T


@dataclass
class Marker:
    """Marker geometry from marker.yaml [m]; ``columns`` patches per row."""

    radius: float
    columns: int
    row_height: float
    tip_offset: float

    @property
    def beta(self) -> float:
        """Angular width of one patch column [rad]."""
        return 2.0 * math.pi / self.columns

    def corners(self) -> np.ndarray:
        """X-corners in {wm}, shape (columns, 3) [m]."""
        a = self.beta * np.arange(self.columns)
        return np.stack([self.radius * np.cos(a), self.radius * np.sin(a), np.zeros_like(a)], axis=1)


class ContractError(Exception):
    """Raised when a file cannot be parsed at all (the remaining checks cannot run)."""


# ----------------------------------------------------------------------------------------------------------
# parsing helpers


def _matrix(value: Any, shape: tuple[int, ...], name: str, errors: list[str]) -> np.ndarray | None:
    """Parse ``value`` as a finite float array of ``shape``; record a violation and return None otherwise."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        errors.append(f"{name}: not numeric")
        return None
    if a.shape != shape:
        errors.append(f"{name}: shape {a.shape}, expected {shape}")
        return None
    if not np.all(np.isfinite(a)):
        errors.append(f"{name}: not finite")
        return None
    return a


def _check_rotation(Rm: np.ndarray, name: str, errors: list[str]) -> None:
    """Record a violation unless ``Rm`` is a proper rotation (R R^T = I, det = +1)."""
    if not np.allclose(Rm @ Rm.T, np.eye(3), atol=ROT_TOL):
        errors.append(f"{name}: not orthonormal (|R R^T - I| = {np.abs(Rm @ Rm.T - np.eye(3)).max():.2e})")
    if abs(np.linalg.det(Rm) - 1.0) > 10 * ROT_TOL:
        errors.append(f"{name}: det = {np.linalg.det(Rm):.6f}, expected +1")


def check_calib(path: Path, errors: list[str]) -> tuple[tuple[int, int], Camera, Camera] | None:
    """Check calib.yaml against docs/design.md and return ((width, height) [px], left, right) or None."""
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict):
        errors.append("calib.yaml: not a mapping")
        return None
    for key in ("image_size", "left", "right", "R", "T"):
        if key not in data:
            errors.append(f"calib.yaml: missing key '{key}'")
    if errors:
        return None
    size = data["image_size"]
    if not (isinstance(size, list) and len(size) == 2 and all(isinstance(s, int) and s > 0 for s in size)):
        errors.append(f"calib.yaml: image_size must be [width, height] positive integers, got {size!r}")
        return None
    cams: list[Camera] = []
    for eye in ("left", "right"):
        block = data[eye]
        if not isinstance(block, dict) or "K" not in block or "dist" not in block:
            errors.append(f"calib.yaml: {eye} needs K and dist")
            return None
        K = _matrix(block["K"], (3, 3), f"{eye}.K", errors)
        dist = np.asarray(block["dist"], dtype=float).ravel()
        if dist.size not in DIST_LENGTHS or not np.all(np.isfinite(dist)):
            errors.append(f"calib.yaml: {eye}.dist has {dist.size} entries, expected one of {DIST_LENGTHS}")
            return None
        if K is None:
            return None
        if not (np.allclose(K[2], [0, 0, 1]) and K[1, 0] == 0 and K[0, 0] > 0 and K[1, 1] > 0):
            errors.append(f"calib.yaml: {eye}.K is not an upper-triangular camera matrix with K[2] = [0, 0, 1]")
        cx, cy = K[0, 2], K[1, 2]
        if not (0 <= cx <= size[0] - 1 and 0 <= cy <= size[1] - 1):
            errors.append(f"calib.yaml: {eye} principal point ({cx}, {cy}) outside the image")
        cams.append(Camera(K, dist, np.eye(3), np.zeros(3)))
    Rm = _matrix(data["R"], (3, 3), "R", errors)
    T = _matrix(np.asarray(data["T"], dtype=float).ravel() if data["T"] is not None else None, (3,), "T", errors)
    if Rm is None or T is None:
        return None
    _check_rotation(Rm, "calib.yaml R", errors)
    baseline = float(np.linalg.norm(T))
    if not 1e-4 < baseline < 0.1:
        errors.append(f"calib.yaml: baseline |T| = {baseline} m, not a plausible length in metres")
    if "world_T_left" in data and data["world_T_left"] is not None:
        W = _matrix(data["world_T_left"], (4, 4), "world_T_left", errors)
        if W is not None:
            _check_rotation(W[:3, :3], "world_T_left rotation", errors)
            if not np.allclose(W[3], [0, 0, 0, 1]):
                errors.append("world_T_left: last row must be [0, 0, 0, 1]")
    cams[1].R, cams[1].T = Rm, T
    return (size[0], size[1]), cams[0], cams[1]


def check_marker(path: Path, errors: list[str]) -> Marker | None:
    """Check marker.yaml (radius, columns, row_height, tip_offset; SI) and return it or None."""
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict):
        errors.append("marker.yaml: not a mapping")
        return None
    missing = [k for k in ("radius", "columns", "row_height", "tip_offset") if k not in data]
    if missing:
        errors.append(f"marker.yaml: missing {missing}")
        return None
    m = Marker(float(data["radius"]), int(data["columns"]), float(data["row_height"]), float(data["tip_offset"]))
    if m.columns != data["columns"] or m.columns < 4 or m.columns % 2:
        errors.append(f"marker.yaml: columns must be an even integer >= 4 (polarity alternates), got {data['columns']}")
    for name, val in (("radius", m.radius), ("row_height", m.row_height), ("tip_offset", m.tip_offset)):
        if not 0 < abs(val) < 0.2:
            errors.append(f"marker.yaml: {name} = {val} is not a plausible length in metres")
    return m


def list_pairs(folder: Path, errors: list[str]) -> list[int]:
    """Pair numbers NN that have both pair_NN_left.png and pair_NN_right.png."""
    found: dict[int, set[str]] = {}
    for p in folder.iterdir():
        mt = PAIR_RE.match(p.name)
        if mt:
            found.setdefault(int(mt.group(1)), set()).add(mt.group(2))
    for n, sides in sorted(found.items()):
        if sides != {"left", "right"}:
            errors.append(f"pair {n:02d}: only {sorted(sides)} image present")
    return sorted(n for n, s in found.items() if s == {"left", "right"})


# ----------------------------------------------------------------------------------------------------------
# geometry


def project(cam: Camera, X_left: np.ndarray) -> np.ndarray:
    """Raw (distorted) pixels of points given in {ll} [m], shape (N, 2) [px]."""
    rvec, _ = cv2.Rodrigues(cam.R)
    uv, _ = cv2.projectPoints(X_left.reshape(-1, 1, 3).astype(np.float64), rvec, cam.T.astype(np.float64),
                              cam.K, cam.dist)
    return uv.reshape(-1, 2)


def cos_view(cam: Camera, X_left: np.ndarray, n_left: np.ndarray) -> np.ndarray:
    """Cosine between outward normals ``n_left`` and the direction from ``X_left`` to the camera centre."""
    d = cam.centre_left[None, :] - X_left
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.sum(d * n_left, axis=1)


def to_gray(img: np.ndarray) -> np.ndarray:
    """Grey float32 image (BGR/BGRA/grey, 8 or 16 bit) in grey levels of its own depth."""
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[:, :, :3]
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.dtype == np.uint8 else img.mean(axis=2)
    return img.astype(np.float32)


def free_radius_px(cam: Camera, marker: Marker, Rm: np.ndarray, t: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Per corner in ``idx``: image distance [px] to the nearest other feature of the pattern.

    Features: the adjacent corners, the row edges (z = +-row_height) and the silhouette (limb) of the
    sleeve, found as surface points of the corner's four patches with 0 < cos_view < 0.05. ``Rm, t`` pose
    {wm} in {ll} [m].
    """
    out = np.empty(len(idx))
    b, r, h = marker.beta, marker.radius, marker.row_height
    for j, i in enumerate(idx):
        c_uv = project(cam, t + Rm @ marker.corners()[i])[0]
        ang = np.linspace((i - 1) * b, (i + 1) * b, 81)
        zz = np.linspace(-h, h, 17)
        A, Z = np.meshgrid(ang, zz)
        pts = np.stack([r * np.cos(A), r * np.sin(A), Z], axis=-1).reshape(-1, 3)
        nrm = np.stack([np.cos(A), np.sin(A), np.zeros_like(A)], axis=-1).reshape(-1, 3)
        X = t[None, :] + pts @ Rm.T
        cv = cos_view(cam, X, nrm @ Rm.T)
        edge = (np.abs(np.abs(pts[:, 2]) - h) < 1e-12) & (cv > 0)  # row edges, visible part
        limb = (cv > 0) & (cv < 0.05)
        nbr = np.zeros(len(pts), dtype=bool)
        nbr[[8 * 81 + 0, 8 * 81 + 80]] = True  # z = 0 at angles (i -+ 1) beta: the adjacent corners
        nbr &= cv > 0
        sel = edge | limb | nbr
        d = np.linalg.norm(project(cam, X[sel]) - c_uv, axis=1) if sel.any() else np.array([np.inf])
        out[j] = float(d.min())
    return out


def subpix_errors(gray: np.ndarray, uv_true: np.ndarray, free_px: np.ndarray, rng: np.random.Generator,
                  ) -> np.ndarray:
    """cv2.cornerSubPix started 1-1.5 px from each true corner; returns result - truth, shape (N, 2) [px].

    ``free_px`` is, per corner, the image distance to the nearest other feature (see ``free_radius_px``):
    the search half-window is half of it (clipped to at most 10 px) so that it covers only the corner's
    four patches; corners whose half-window would be below SUBPIX_MIN_HALF px are skipped (NaN).
    """
    out = np.full((len(uv_true), 2), np.nan)
    h, w = gray.shape
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 200, 1e-4)
    for j, (uv, dn) in enumerate(zip(uv_true, free_px)):
        half = int(min(np.floor(0.5 * dn), SUBPIX_MAX_HALF))
        if half < SUBPIX_MIN_HALF:
            continue
        ang = rng.uniform(0, 2 * math.pi)
        start = uv + rng.uniform(1.0, 1.5) * np.array([math.cos(ang), math.sin(ang)])
        if not (half + 2 <= start[0] <= w - half - 3 and half + 2 <= start[1] <= h - half - 3):
            continue
        pt = start.reshape(1, 1, 2).astype(np.float32)
        pt = cv2.cornerSubPix(gray, pt, (half, half), (-1, -1), crit)
        out[j] = pt.reshape(2).astype(float) - uv
    return out


def model_fit_errors(gray: np.ndarray, cam: Camera, marker: Marker, Rm: np.ndarray, t: np.ndarray,
                     idx: np.ndarray, free_px: np.ndarray, oversample: int = 8) -> np.ndarray:
    """Sub-pixel alignment of the image with the ideal pattern at each corner in ``idx``.

    Around each corner a window (half-size 70 % of ``free_px``, at most MODEL_MAX_HALF px, so that it holds
    only the corner's four patches) is compared with the ideal two-level pattern obtained by casting the rays
    of an ``oversample``-times finer grid of raw pixel positions (cv2.undistortPoints) at the sleeve posed by
    ``Rm, t`` [m] in {ll}, integrated over each pixel and blurred by a Gaussian of fitted width. The model
    ``image = A(x) + G(x) * template(x + d)`` with quadratic offset and gain fields A, G (shading) is fitted
    by least squares; the image's pattern then sits at ``-d`` from the truth. Returns the (N, 2) offsets
    image - truth [px]; NaN where the window would be smaller than MODEL_MIN_HALF px.
    """
    out = np.full((len(idx), 2), np.nan)
    h_img, w_img = gray.shape
    margin = 4
    for j, (i, free) in enumerate(zip(idx, free_px)):
        half = int(min(np.floor(0.7 * free), MODEL_MAX_HALF))
        if half < MODEL_MIN_HALF:
            continue
        c_uv = project(cam, (t + Rm @ marker.corners()[i])[None, :])[0]
        cu, cv_ = int(round(c_uv[0])), int(round(c_uv[1]))
        if not (half + margin <= cu < w_img - half - margin and half + margin <= cv_ < h_img - half - margin):
            continue
        window = _Window(cu, cv_, half, margin, oversample)
        tmpl, valid = ideal_pattern(cam, marker, Rm, t, window)
        d = fit_offset(gray, window, tmpl, valid)
        if d is not None:
            out[j] = [-d[0], -d[1]]
    return out


@dataclass(frozen=True)
class _Window:
    """A model-fit window: centre pixel (cu, cv), half-size and margin [px], oversampling factor."""

    cu: int
    cv: int
    half: int
    margin: int
    O: int

    @property
    def n_px(self) -> int:
        """Pixels per side of the window plus margin."""
        return 2 * (self.half + self.margin) + 1

    @property
    def origin(self) -> tuple[float, float]:
        """Raw pixel position of the fine grid's corner: fine sample (a, b) is at origin + (a + 0.5) / O - 0.5."""
        return self.cu - self.half - self.margin - 0.5, self.cv - self.half - self.margin - 0.5


def ideal_pattern(cam: Camera, marker: Marker, Rm: np.ndarray, t: np.ndarray,
                  w: _Window) -> tuple[np.ndarray, np.ndarray]:
    """The ideal two-level pattern (dark 0, white 1) over the window's fine grid, integrated over one
    pixel, and the share of each pixel whose rays hit the checker rows (ray cast at the posed sleeve)."""
    O, n_px = w.O, w.n_px
    g0u, g0v = w.origin
    fa = g0u + (np.arange(n_px * O) + 0.5) / O
    fb = g0v + (np.arange(n_px * O) + 0.5) / O
    FU, FV = np.meshgrid(fa, fb)
    uv = np.stack([FU.ravel(), FV.ravel()], axis=1)
    nrm = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.K, cam.dist, criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    d = np.concatenate([nrm, np.ones((len(nrm), 1))], axis=1) @ cam.R  # ray in {ll}: R^T [x, y, 1]
    o_m = Rm.T @ (cam.centre_left - t)
    d_m = d @ Rm
    a2 = d_m[:, 0] ** 2 + d_m[:, 1] ** 2
    b2 = 2 * (o_m[0] * d_m[:, 0] + o_m[1] * d_m[:, 1])
    c2 = o_m[0] ** 2 + o_m[1] ** 2 - marker.radius**2
    disc = b2 * b2 - 4 * a2 * c2
    with np.errstate(invalid="ignore"):
        s = (-b2 - np.sqrt(disc)) / (2 * a2)
    P = o_m[None, :] + s[:, None] * d_m
    ok = (disc > 0) & (s > 0) & (np.abs(P[:, 2]) < marker.row_height)
    ang = np.mod(np.arctan2(np.where(ok, P[:, 1], 0.0), np.where(ok, P[:, 0], 1.0)), 2 * math.pi)
    k = np.minimum((ang / marker.beta).astype(int), marker.columns - 1)
    dark = (k % 2 == 0) == (P[:, 2] > 0)
    tmpl = np.where(dark, 0.0, 1.0).astype(np.float32).reshape(n_px * O, n_px * O)
    valid = ok.astype(np.float32).reshape(n_px * O, n_px * O)
    return cv2.blur(tmpl, (O, O)), cv2.blur(valid, (O, O))  # integrate over one pixel


def fit_offset(gray: np.ndarray, w: _Window, tmpl: np.ndarray, valid: np.ndarray) -> np.ndarray | None:
    """Offset d [px] of the template that best explains the image window as A(x) + G(x) template(x + d)
    (quadratic A, G; Gaussian blur of fitted width); None where the window leaves the sleeve or the
    fit runs off."""
    O, half, cu, cv_ = w.O, w.half, w.cu, w.cv
    g0u, g0v = w.origin
    win_u = np.arange(cu - half, cu + half + 1, dtype=float)
    win_v = np.arange(cv_ - half, cv_ + half + 1, dtype=float)
    WU, WV = np.meshgrid(win_u, win_v)
    img = gray[cv_ - half:cv_ + half + 1, cu - half:cu + half + 1].astype(float).ravel()
    # after the even O x O box, fine index a is centred at g0 + a / O: pixel centre p sits at (p - g0) * O
    mu0 = ((WU - g0u) * O).astype(np.float32)
    mv0 = ((WV - g0v) * O).astype(np.float32)
    mask = cv2.remap(valid, mu0, mv0, cv2.INTER_LINEAR).ravel() > 0.999
    if mask.mean() < 0.9:
        return None
    x = ((WU - cu) / half).ravel()[mask]
    y = ((WV - cv_) / half).ravel()[mask]
    poly = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)
    b_img = img[mask]
    cache: dict[float, np.ndarray] = {}

    def cost(par: np.ndarray) -> float:
        du, dv, sig = float(par[0]), float(par[1]), float(np.clip(par[2], 0.2, 3.0))
        key = round(sig, 4)
        if key not in cache:
            cache[key] = cv2.GaussianBlur(tmpl, (0, 0), sig * O)
        tb = cv2.remap(cache[key], mu0 + np.float32(du * O), mv0 + np.float32(dv * O), cv2.INTER_LINEAR)
        tv = tb.ravel()[mask].astype(float)
        A = np.concatenate([poly, poly * tv[:, None]], axis=1)
        coef, *_ = np.linalg.lstsq(A, b_img, rcond=None)
        r = b_img - A @ coef
        return float(r @ r)

    best = min((cost(np.array([0.0, 0.0, sg])), sg) for sg in (0.6, 0.9, 1.2, 1.6, 2.2))[1]
    res = minimize(cost, np.array([0.0, 0.0, best]), method="Nelder-Mead",
                   options={"xatol": 2e-4, "fatol": 1e-9, "maxiter": 400,
                            "initial_simplex": np.array([[0, 0, best], [0.3, 0, best], [0, 0.3, best],
                                                         [0, 0, best + 0.2]])})
    if abs(res.x[0]) < w.margin - 1 and abs(res.x[1]) < w.margin - 1:
        return np.asarray(res.x[:2], float)
    return None


def sample(gray: np.ndarray, uv: np.ndarray, half: float) -> float:
    """Mean grey of a (2 half + 1)^2 px square around ``uv`` (bilinear, sub-pixel centred)."""
    size = int(2 * max(1, round(half)) + 1)
    patch = cv2.getRectSubPix(gray, (size, size), (float(uv[0]), float(uv[1])))
    return float(patch.mean())


# ----------------------------------------------------------------------------------------------------------
# the check


@dataclass
class _Tally:
    """What the per-pair checks measure, gathered over the dataset."""

    proj_err: float = 0.0
    cos_err: float = 0.0
    tip_err: float = 0.0
    sub_err: list[np.ndarray] = field(default_factory=list)
    fit_err: list[np.ndarray] = field(default_factory=list)
    n_sub_skipped: int = 0
    n_patch: int = 0
    n_patch_wrong: int = 0
    patch_ratio_min: float = math.inf
    visible_counts: list[int] = field(default_factory=list)


def check_dataset(folder: str | Path, seed: int = 0, model_fit: bool = True) -> dict[str, Any]:
    """Check a dataset folder against docs/design.md; returns a JSON-able summary with ``violations``.

    Measured quantities: ``proj_err_max_px`` (truth uv vs projection), ``cos_err_max``, ``tip_err_max_m``,
    ``subpix`` (cornerSubPix vs truth: n, rms_px, max_px, bias_px), ``model_fit`` (image pattern vs truth by
    fitting the ideal pattern, see ``model_fit_errors``; skipped when ``model_fit`` is False) and ``patches``
    (colour samples compared / wrong).
    """
    folder = Path(folder)
    errors: list[str] = []
    summary: dict[str, Any] = {"folder": str(folder), "violations": errors}
    for name in ("calib.yaml", "marker.yaml", "truth.json"):
        if not (folder / name).is_file():
            errors.append(f"missing {name}")
    if errors:
        summary["ok"] = False
        return summary
    calib = check_calib(folder / "calib.yaml", errors)
    marker = check_marker(folder / "marker.yaml", errors)
    numbers = list_pairs(folder, errors)
    truth = json.loads((folder / "truth.json").read_text())
    if not isinstance(truth, list):
        errors.append("truth.json: not a list")
    if calib is None or marker is None or not isinstance(truth, list):
        summary["ok"] = False
        return summary
    size, left, right = calib
    if numbers != list(range(len(truth))):
        errors.append(f"pairs on disk {numbers} != 0..{len(truth) - 1} from truth.json")
    summary.update(pairs=len(truth), image_size=list(size), columns=marker.columns)

    rng = np.random.default_rng(seed)
    tally = _Tally()
    for idx, entry in enumerate(truth):
        pose = _check_pose(entry, idx, marker, errors, tally)
        if pose is None:
            continue
        for side, cam in (("left", left), ("right", right)):
            _check_view(folder, idx, side, cam, size, marker, entry, pose, model_fit, rng, errors, tally)
    _summarise(summary, tally, model_fit, errors)
    summary["ok"] = not errors
    return summary


def _check_pose(entry: Any, idx: int, marker: Marker, errors: list[str],
                tally: _Tally) -> tuple[np.ndarray, np.ndarray] | None:
    """One truth.json entry's keys, pose (R, t of {wm} in {ll}) and tip; (R, t) or None."""
    tag = f"truth[{idx}]"
    if not isinstance(entry, dict):
        errors.append(f"{tag}: not an object")
        return None
    missing = [k for k in ("pair", "R", "t", "tip", "corners_left", "corners_right") if k not in entry]
    if missing:
        errors.append(f"{tag}: missing {missing}")
        return None
    if entry["pair"] != idx:
        errors.append(f"{tag}: pair = {entry['pair']!r}, expected {idx}")
    Rm = _matrix(entry["R"], (3, 3), f"{tag}.R", errors)
    t = _matrix(entry["t"], (3,), f"{tag}.t", errors)
    tip = _matrix(entry["tip"], (3,), f"{tag}.tip", errors)
    if Rm is None or t is None or tip is None:
        return None
    _check_rotation(Rm, f"{tag}.R", errors)
    e = float(np.linalg.norm(tip - (t + Rm @ np.array([0.0, 0.0, marker.tip_offset]))))
    tally.tip_err = max(tally.tip_err, e)
    if e > TIP_TOL_M:
        errors.append(f"{tag}: tip differs from t + R [0, 0, tip_offset] by {e:.3e} m")
    if not 0.005 < t[2] < 1.0:
        errors.append(f"{tag}: marker depth t_z = {t[2]} m is not in front of the camera")
    return Rm, t


def _check_view(folder: Path, idx: int, side: str, cam: Camera, size: tuple[int, int], marker: Marker,
                entry: dict[str, Any], pose: tuple[np.ndarray, np.ndarray], model_fit: bool,
                rng: np.random.Generator, errors: list[str], tally: _Tally) -> None:
    """One side of one pair: the listed corners against the projection, then the image's pixels."""
    Rm, t = pose
    corners = _check_corners(entry[f"corners_{side}"], f"truth[{idx}].corners_{side}", cam, marker, Rm, t, errors,
                             tally)
    if corners is None:
        return
    uv_p, cv = corners
    img_path = folder / f"pair_{idx:02d}_{side}.png"
    if not img_path.is_file():
        return
    img = cv2.imread(str(img_path), cv2.IMREAD_UNCHANGED)
    if img is None:
        errors.append(f"{img_path.name}: unreadable")
        return
    if (img.shape[1], img.shape[0]) != size:
        errors.append(f"{img_path.name}: size {img.shape[1]}x{img.shape[0]} != calibrated {size}")
        return
    if img.dtype not in (np.uint8, np.uint16):
        errors.append(f"{img_path.name}: dtype {img.dtype}, expected 8 or 16 bit")
    gray = to_gray(img)

    # pixels agree with truth: cornerSubPix near each well-visible corner
    good = np.flatnonzero(cv > SUBPIX_COS_MIN)
    if good.size:
        free = free_radius_px(cam, marker, Rm, t, good)
        errs = subpix_errors(gray, uv_p[good], free, rng)
        tally.sub_err.extend(errs[np.isfinite(errs[:, 0])])
        tally.n_sub_skipped += int(np.sum(~np.isfinite(errs[:, 0])))
        if model_fit:
            errs = model_fit_errors(gray, cam, marker, Rm, t, good, free)
            tally.fit_err.extend(errs[np.isfinite(errs[:, 0])])
    _compare_patches(_sample_patches(gray, cam, size, marker, Rm, t), marker, img_path.name, errors, tally)


def _check_corners(corners: Any, stag: str, cam: Camera, marker: Marker, Rm: np.ndarray, t: np.ndarray,
                   errors: list[str], tally: _Tally) -> tuple[np.ndarray, np.ndarray] | None:
    """The corners list ``corners`` of one side against the projection and the recomputed cos_view; (projected
    uv, listed cos_view) or None when the list is malformed."""
    a = marker.beta * np.arange(marker.columns)
    N = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    X = t[None, :] + marker.corners() @ Rm.T  # corners in {ll}
    if not isinstance(corners, list) or len(corners) != marker.columns:
        errors.append(f"{stag}: expected a list of {marker.columns} corners")
        return None
    try:
        idxs = [c["index"] for c in corners]
        uv = np.array([c["uv"] for c in corners], dtype=float)
        cv = np.array([c["cos_view"] for c in corners], dtype=float)
    except (KeyError, TypeError, ValueError):
        errors.append(f"{stag}: entries need index, uv [u, v] and cos_view")
        return None
    if idxs != list(range(marker.columns)):
        errors.append(f"{stag}: indices {idxs} are not 0..{marker.columns - 1} in order")
        return None
    if uv.shape != (marker.columns, 2) or not np.all(np.isfinite(uv)) or not np.all(np.abs(cv) <= 1 + 1e-12):
        errors.append(f"{stag}: uv must be finite [u, v], cos_view in [-1, 1]")
        return None
    uv_p = project(cam, X)
    e = float(np.abs(uv - uv_p).max())
    tally.proj_err = max(tally.proj_err, e)
    if e > PROJ_TOL_PX:
        errors.append(f"{stag}: uv differ from the projection of the posed corners by up to {e:.3e} px")
    cv_p = cos_view(cam, X, N @ Rm.T)
    e = float(np.abs(cv - cv_p).max())
    tally.cos_err = max(tally.cos_err, e)
    if e > COS_TOL:
        errors.append(f"{stag}: cos_view differs from the recomputed cosine by up to {e:.3e}")
    tally.visible_counts.append(int(np.sum(cv > 0)))
    return uv_p, cv


def _sample_patches(gray: np.ndarray, cam: Camera, size: tuple[int, int], marker: Marker, Rm: np.ndarray,
                    t: np.ndarray) -> dict[tuple[int, int], float]:
    """Mean grey at the centre of every well-visible patch, keyed (row: 1 upper / -1 lower, column)."""
    ac = marker.beta * (np.arange(marker.columns) + 0.5)
    nc = np.stack([np.cos(ac), np.sin(ac), np.zeros_like(ac)], axis=1)
    samples: dict[tuple[int, int], float] = {}
    for row, zc in ((1, 0.5 * marker.row_height), (-1, -0.5 * marker.row_height)):
        pc = np.stack([marker.radius * np.cos(ac), marker.radius * np.sin(ac), np.full_like(ac, zc)], 1)
        Xc = t[None, :] + pc @ Rm.T
        cvc = cos_view(cam, Xc, nc @ Rm.T)
        uvc = project(cam, Xc)
        # sampling half-size: 20 % of the projected half row height
        hpx = np.linalg.norm(project(cam, Xc + Rm[:, 2] * (0.25 * marker.row_height)) - uvc, axis=1)
        for k in np.flatnonzero(cvc > PATCH_COS_MIN):
            u, v = uvc[k]
            if 3 <= u <= size[0] - 4 and 3 <= v <= size[1] - 4:
                samples[(row, int(k))] = sample(gray, uvc[k], 0.4 * hpx[k])
    return samples


def _compare_patches(samples: dict[tuple[int, int], float], marker: Marker, name: str, errors: list[str],
                     tally: _Tally) -> None:
    """Patch colours: upper row patch k dark for even k, bright for odd k; lower row opposite. Each
    sampled patch is compared with its vertical and next horizontal neighbour (same shading)."""
    for (row, k), val in samples.items():
        dark = (k % 2 == 0) == (row == 1)
        for other in ((-row, k), (row, (k + 1) % marker.columns)):
            if other not in samples:
                continue
            row2, k2 = other
            dark2 = (k2 % 2 == 0) == (row2 == 1)
            if dark == dark2:
                continue
            lo, hi = (val, samples[other]) if dark else (samples[other], val)
            tally.n_patch += 1
            ratio = (hi + 1.0) / (lo + 1.0)
            tally.patch_ratio_min = min(tally.patch_ratio_min, ratio)
            if ratio < PATCH_MIN_CONTRAST:
                tally.n_patch_wrong += 1
                errors.append(f"{name}: patch {'upper' if row == 1 else 'lower'} {k} "
                              f"({'dark' if dark else 'bright'} expected, grey {val:.1f}) vs "
                              f"{'upper' if row2 == 1 else 'lower'} {k2} (grey {samples[other]:.1f})")


def _summarise(summary: dict[str, Any], tally: _Tally, model_fit: bool, errors: list[str]) -> None:
    """The measured numbers into ``summary``, and the dataset-wide tolerance checks into ``errors``."""
    sub_vec = np.array(tally.sub_err).reshape(-1, 2)
    sub = np.linalg.norm(sub_vec, axis=1)
    bias = sub_vec.mean(axis=0) if sub.size else np.zeros(2)
    fit_vec = np.array(tally.fit_err).reshape(-1, 2)
    fit = np.linalg.norm(fit_vec, axis=1)
    fit_bias = fit_vec.mean(axis=0) if fit.size else np.zeros(2)
    visible = tally.visible_counts
    summary.update(
        proj_err_max_px=tally.proj_err,
        cos_err_max=tally.cos_err,
        tip_err_max_m=tally.tip_err,
        visible_corners_min=min(visible) if visible else 0,
        visible_corners_max=max(visible) if visible else 0,
        subpix={
            "n": int(sub.size),
            "rms_px": float(np.sqrt(np.mean(sub**2))) if sub.size else None,
            "median_px": float(np.median(sub)) if sub.size else None,
            "max_px": float(sub.max()) if sub.size else None,
            "bias_px": [float(bias[0]), float(bias[1])],
            "skipped_near_features": tally.n_sub_skipped,
        },
        model_fit={
            "n": int(fit.size),
            "rms_px": float(np.sqrt(np.mean(fit**2))) if fit.size else None,
            "max_px": float(fit.max()) if fit.size else None,
            "bias_px": [float(fit_bias[0]), float(fit_bias[1])],
        },
        patches={"pairs_compared": tally.n_patch, "wrong": tally.n_patch_wrong,
                 "min_contrast": None if math.isinf(tally.patch_ratio_min) else tally.patch_ratio_min},
        tolerances={"proj_px": PROJ_TOL_PX, "cos": COS_TOL, "tip_m": TIP_TOL_M, "subpix_rms_px": SUBPIX_RMS_TOL_PX,
                    "subpix_max_px": SUBPIX_MAX_TOL_PX,
                    "subpix_min_half_px": SUBPIX_MIN_HALF, "model_rms_px": MODEL_RMS_TOL_PX,
                    "model_max_px": MODEL_MAX_TOL_PX, "model_bias_px": MODEL_BIAS_TOL_PX,
                    "patch_contrast": PATCH_MIN_CONTRAST},
    )
    if sub.size == 0:
        errors.append("no well-visible corner inside the images: cornerSubPix check could not run")
    else:
        if summary["subpix"]["rms_px"] > SUBPIX_RMS_TOL_PX:
            errors.append(f"cornerSubPix vs truth RMS {summary['subpix']['rms_px']:.3f} px > {SUBPIX_RMS_TOL_PX}")
        if summary["subpix"]["max_px"] > SUBPIX_MAX_TOL_PX:
            errors.append(f"cornerSubPix vs truth max {summary['subpix']['max_px']:.3f} px > {SUBPIX_MAX_TOL_PX}")
    if model_fit:
        if fit.size == 0:
            errors.append("no corner window for the model fit")
        else:
            if summary["model_fit"]["rms_px"] > MODEL_RMS_TOL_PX:
                errors.append(f"image pattern vs truth (model fit) RMS {summary['model_fit']['rms_px']:.3f} px "
                              f"> {MODEL_RMS_TOL_PX}")
            if summary["model_fit"]["max_px"] > MODEL_MAX_TOL_PX:
                errors.append(f"image pattern vs truth (model fit) max {summary['model_fit']['max_px']:.3f} px "
                              f"> {MODEL_MAX_TOL_PX}")
            if float(np.linalg.norm(fit_bias)) > MODEL_BIAS_TOL_PX:
                errors.append(f"image pattern vs truth (model fit) mean offset {fit_bias.round(3).tolist()} px "
                              f"(pixel-centre convention or frames?)")
    if tally.n_patch == 0:
        errors.append("no visible patch pair to check the pattern colours")


# ----------------------------------------------------------------------------------------------------------
# comparing `wristmark track --json` output with truth.json


def pair_paths(folder: str | Path) -> list[tuple[Path, Path]]:
    """(left, right) image paths of a dataset folder, in pair order."""
    folder = Path(folder)
    n = len(json.loads((folder / "truth.json").read_text()))
    return [(folder / f"pair_{i:02d}_left.png", folder / f"pair_{i:02d}_right.png") for i in range(n)]


def run_track(folder: str | Path, exe: str | Path, timeout: float = 600.0) -> tuple[list[dict[str, Any]], float]:
    """Run ``EXE track --calib --marker LEFT RIGHT ... --json`` on all pairs of ``folder``.

    Returns the parsed JSON lines (one per pair) and the wall-clock seconds of the whole call."""
    import subprocess
    import time

    folder = Path(folder)
    args = [str(exe), "track", "--calib", str(folder / "calib.yaml"), "--marker", str(folder / "marker.yaml")]
    for left, right in pair_paths(folder):
        args += [str(left), str(right)]
    args.append("--json")
    t0 = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
    dt = time.perf_counter() - t0
    if proc.returncode != 0 and not proc.stdout.strip():
        raise RuntimeError(f"wristmark track failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    return [json.loads(line) for line in proc.stdout.splitlines() if line.strip()], dt


def score_track(folder: str | Path, results: list[dict[str, Any]], match_px: float = 3.0) -> dict[str, Any]:
    """Compare tracker results with truth.json: tip error [m] (both in {ll}), corner error [px].

    Each reported corner (corners_left / corners_right, raw pixels) is matched to the nearest true corner
    facing that camera (cos_view > 0); matches farther than ``match_px`` count as unmatched. Returns per-pair
    rows and aggregates (success rate, tip error mean / max, corner error RMS / max, failures with reasons)."""
    folder = Path(folder)
    truth = json.loads((folder / "truth.json").read_text())
    rows: list[dict[str, Any]] = []
    corner_err: list[float] = []
    unmatched = 0
    for i, tr in enumerate(truth):
        o = results[i] if i < len(results) else {"ok": False, "reason": "no output line"}
        row: dict[str, Any] = {"pair": i, "ok": bool(o.get("ok"))}
        if not o.get("ok"):
            row["reason"] = o.get("reason")
            rows.append(row)
            continue
        row["tip_err_m"] = float(np.linalg.norm(np.asarray(o["tip"], float) - np.asarray(tr["tip"], float)))
        row["axis_err_deg"] = float(np.degrees(np.arccos(np.clip(
            np.asarray(o["R"], float)[:, 2] @ np.asarray(tr["R"], float)[:, 2], -1, 1))))
        row["rms_px"] = o.get("rms_px")
        row["time_ms"] = o.get("time_ms")
        errs: list[float] = []
        for side in ("left", "right"):
            tuv = np.array([c["uv"] for c in tr[f"corners_{side}"] if c["cos_view"] > 0], float).reshape(-1, 2)
            for uv in np.asarray(o.get(f"corners_{side}", []), float).reshape(-1, 2):
                d = np.linalg.norm(tuv - uv, axis=1).min() if len(tuv) else np.inf
                if d <= match_px:
                    errs.append(float(d))
                else:
                    unmatched += 1
        row["corner_err_max_px"] = max(errs) if errs else None
        row["corners"] = len(errs)
        corner_err.extend(errs)
        rows.append(row)
    ok = [r for r in rows if r["ok"]]
    tips = np.array([r["tip_err_m"] for r in ok])
    ce = np.array(corner_err)
    times = [r["time_ms"] for r in ok if r.get("time_ms") is not None]
    return {
        "pairs": len(truth),
        "success_rate": len(ok) / max(len(truth), 1),
        "tip_err_mean_mm": float(tips.mean() * 1e3) if tips.size else None,
        "tip_err_median_mm": float(np.median(tips) * 1e3) if tips.size else None,
        "tip_err_max_mm": float(tips.max() * 1e3) if tips.size else None,
        "corner_err_rms_px": float(np.sqrt(np.mean(ce**2))) if ce.size else None,
        "corner_err_median_px": float(np.median(ce)) if ce.size else None,
        "corner_err_max_px": float(ce.max()) if ce.size else None,
        "corners_matched": int(ce.size),
        "corners_unmatched": unmatched,
        "tracker_time_ms_median": float(np.median(times)) if times else None,
        "failures": [{"pair": r["pair"], "reason": r.get("reason")} for r in rows if not r["ok"]],
        "rows": rows,
    }


def main(argv: list[str] | None = None) -> int:
    """Command line: check DIR, print the JSON summary, exit 1 on a violation (2 on bad usage)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m wristmark_testing.independent_dataset_check DIR", file=sys.stderr)
        return 2
    if not Path(args[0]).is_dir():
        print(f"error: {args[0]} is not a folder", file=sys.stderr)
        return 2
    summary = check_dataset(args[0])
    print(json.dumps(summary, indent=1))
    return 0 if summary["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
