"""Stereo calibration from board views: per-camera cv2.calibrateCamera, then cv2.stereoCalibrate
with the intrinsics as a guess (CALIB_USE_INTRINSIC_GUESS); views whose reprojection error is an
outlier are dropped and named. X_right = R X_left + T [m]; errors in pixels."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from wristmark.cvs.calibration.board import BoardDetector, BoardView
from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.errors import InputError

Array = NDArray[np.float64]
MIN_VIEWS = 3
_CRIT = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-7)


@dataclass(frozen=True)
class StereoView:
    """One stereo view: its name, image size (w, h) and the board in each image (None: not found)."""

    name: str
    size: tuple[int, int]
    left: BoardView | None
    right: BoardView | None


@dataclass
class ViewError:
    """RMS reprojection error of one view in each camera [px]; ``used`` False when dropped
    (``reason`` says why)."""

    name: str
    left_px: float = float("nan")
    right_px: float = float("nan")
    used: bool = False
    reason: str = ""


@dataclass
class StereoCalibration:
    """The calibrated pair, the stereo RMS [px], each camera's RMS alone [px], per-view errors."""

    camera: StereoCamera
    rms_px: float
    mono_rms_px: tuple[float, float]
    views: list[ViewError] = field(default_factory=list)

    @property
    def dropped(self) -> list[ViewError]:
        """Views not used in the final stereo solve."""
        return [v for v in self.views if not v.used]


def detect_views(pairs: Iterable[tuple[str, NDArray[np.uint8], NDArray[np.uint8]]], detector: BoardDetector,
                 total: int | None = None, progress: bool = True) -> list[StereoView]:
    """Find the board in every (name, left, right) pair; a progress bar over the views."""
    out = []
    for name, left, right in tqdm(pairs, total=total, desc="board views", unit="view", disable=not progress,
                                  leave=False):
        if left.shape[:2] != right.shape[:2]:
            raise InputError(f"{name}: left and right images differ in size ({left.shape[1]}x{left.shape[0]} vs "
                             f"{right.shape[1]}x{right.shape[0]})")
        out.append(StereoView(name, (int(left.shape[1]), int(left.shape[0])), detector.detect(left),
                              detector.detect(right)))
    return out


def _outliers(err: Array, floor_px: float) -> NDArray[np.bool_]:
    """Views whose error is far above the others': > median + 5 robust sigmas and > floor_px."""
    med = float(np.median(err))
    mad = 1.4826 * float(np.median(np.abs(err - med)))
    return (err > med + 5.0 * max(mad, 0.1 * med)) & (err > floor_px)


def _f32(a: Array, cols: int) -> NDArray[np.float32]:
    return np.ascontiguousarray(a, np.float32).reshape(-1, 1, cols)


def _mono(views: list[BoardView], size: tuple[int, int], flags: int) -> tuple[float, Camera, Array]:
    rms, K, D, _r, _t, _si, _se, per = cv2.calibrateCameraExtended(  # type: ignore[call-overload]
        [_f32(v.object_points, 3) for v in views], [_f32(v.image_points, 2) for v in views], size, None, None,
        flags=flags, criteria=_CRIT)
    return float(rms), Camera(np.asarray(K, float), np.asarray(D, float).ravel()[:5]), np.asarray(per).ravel()


def _common(v: StereoView) -> tuple[Array, Array, Array]:
    """Object points and left/right image points of the corners both cameras found."""
    assert v.left is not None and v.right is not None
    ids, il, ir = np.intersect1d(v.left.ids, v.right.ids, return_indices=True)
    return v.left.object_points[il], v.left.image_points[il], v.right.image_points[ir]


def calibrate_stereo(views: list[StereoView], min_common: int = 6, outlier_floor_px: float = 0.5,
                     flags: int = 0) -> StereoCalibration:
    """Calibrate the pair from ``views`` (see the module docstring); ``flags`` go to
    calibrateCamera (e.g. cv2.CALIB_FIX_K3). InputError when fewer than 3 usable views remain."""
    if not views:
        raise InputError("no stereo views given")
    size = views[0].size
    for v in views:
        if v.size != size:
            raise InputError(f"{v.name}: image size {v.size[0]}x{v.size[1]} differs from {size[0]}x{size[1]} "
                             "of the first view: calibrate from images of one resolution")
    errors = {v.name: ViewError(v.name) for v in views}
    for v in views:
        if v.left is None or v.right is None:
            miss = "left" if v.left is None else "right"
            errors[v.name].reason = f"board not found in the {miss} image" if (v.left or v.right) else \
                "board not found in either image"
        elif len(_common(v)[0]) < min_common:
            errors[v.name].reason = f"fewer than {min_common} corners seen by both cameras"
    cams, mono_rms = [], []
    for side in ("left", "right"):
        mono = [v for v in views if getattr(v, side) is not None]
        if len(mono) < MIN_VIEWS:
            raise InputError(f"the board was found in only {len(mono)} {side} images (need >= {MIN_VIEWS}): "
                             "check --board (inner corners for a chessboard) and the images")
        rms, cam, per = _mono([getattr(v, side) for v in mono], size, flags)
        bad = _outliers(per, outlier_floor_px)
        if bad.any() and len(mono) - int(bad.sum()) >= MIN_VIEWS:
            for v, e, b in zip(mono, per, bad):
                if b:
                    errors[v.name].reason = errors[v.name].reason or f"{side} view an outlier ({e:.2f} px)"
            rms, cam, _ = _mono([getattr(v, side) for v, b in zip(mono, bad) if not b], size, flags)
        cams.append(cam)
        mono_rms.append(rms)
    stereo = [v for v in views if not errors[v.name].reason]
    while True:
        if len(stereo) < MIN_VIEWS:
            raise InputError(f"only {len(stereo)} views show the board in both images (need >= {MIN_VIEWS})")
        rms, pair, per = _stereo(stereo, cams, size)
        for v, (el, er) in zip(stereo, per):
            errors[v.name].left_px, errors[v.name].right_px = float(el), float(er)
        bad = _outliers(np.hypot(per[:, 0], per[:, 1]) / np.sqrt(2.0), outlier_floor_px)
        if not bad.any() or len(stereo) - int(bad.sum()) < MIN_VIEWS:
            break
        for v, b in zip(stereo, bad):
            if b:
                errors[v.name].reason = "stereo reprojection error an outlier"
        stereo = [v for v, b in zip(stereo, bad) if not b]
    for v in stereo:
        errors[v.name].used = True
    return StereoCalibration(pair, rms, (mono_rms[0], mono_rms[1]), [errors[v.name] for v in views])


def _stereo(views: list[StereoView], cams: list[Camera], size: tuple[int, int]) -> tuple[float, StereoCamera, Array]:
    obj, L, R = zip(*(_common(v) for v in views))
    out = cv2.stereoCalibrateExtended(  # type: ignore[call-overload]
        [_f32(o, 3) for o in obj], [_f32(p, 2) for p in L], [_f32(p, 2) for p in R],
        cams[0].K.copy(), cams[0].dist.copy(), cams[1].K.copy(), cams[1].dist.copy(), size,
        None, None, flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=_CRIT)
    rms, K1, D1, K2, D2, Rm, T = out[:7]
    per = np.asarray(out[-1], float).reshape(-1, 2)
    cam = StereoCamera(size, Camera(np.asarray(K1, float), np.asarray(D1, float).ravel()[:5]),
                       Camera(np.asarray(K2, float), np.asarray(D2, float).ravel()[:5]),
                       np.asarray(Rm, float), np.asarray(T, float).ravel())
    return float(rms), cam, per
