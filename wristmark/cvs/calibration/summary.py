"""A human summary of a stereo calibration: focal lengths, principal points, baseline, field of
view and the rectified overlap (``wristmark calib show``)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from wristmark.cvs.camera import StereoCamera


@dataclass(frozen=True)
class CameraSummary:
    """One camera: focal lengths fx, fy and principal point cx, cy [px]; field of view [deg]."""

    fx: float
    fy: float
    cx: float
    cy: float
    hfov_deg: float
    vfov_deg: float


@dataclass(frozen=True)
class CalibrationSummary:
    """Both cameras, the baseline [mm], the angle between the optical axes [deg] and the rectified
    overlap [%]: the share of the left image's rectified field of view (cv2.stereoRectify) that
    the right camera also sees, for scene points at infinity and at ``working_distance_m``."""

    image_size: tuple[int, int]
    left: CameraSummary
    right: CameraSummary
    baseline_mm: float
    vergence_deg: float
    rectified_overlap_pct: float
    working_distance_m: float
    overlap_at_working_distance_pct: float
    has_world_T_left: bool


def _camera(K: np.ndarray, size: tuple[int, int]) -> CameraSummary:
    fovx, fovy, _f, _pp, _ar = cv2.calibrationMatrixValues(np.asarray(K, float), size, 0.0, 0.0)
    return CameraSummary(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), float(fovx), float(fovy))


def _outline(K: np.ndarray, D: np.ndarray, R: np.ndarray, P: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """The image border mapped into the rectified image (convex hull, float32 for OpenCV)."""
    w, h = size
    t = np.linspace(0.0, 1.0, 33)
    border = np.concatenate([np.c_[t * (w - 1), 0 * t], np.c_[(w - 1) + 0 * t, t * (h - 1)],
                             np.c_[(1 - t) * (w - 1), (h - 1) + 0 * t], np.c_[0 * t, (1 - t) * (h - 1)]])
    uv = cv2.undistortPoints(border.reshape(-1, 1, 2), K, D, R=R, P=P).reshape(-1, 2)
    return cv2.convexHull(uv.astype(np.float32))


def _overlap(left: np.ndarray, right: np.ndarray, shift: float) -> float:
    area, _ = cv2.intersectConvexConvex(left, right + np.array([shift, 0.0], np.float32))
    return 100.0 * float(area) / float(cv2.contourArea(left))


def summarize(cam: StereoCamera, working_distance_m: float = 0.08) -> CalibrationSummary:
    """Summary of a validated calibration; overlap also at ``working_distance_m`` [m]."""
    size = (int(cam.image_size[0]), int(cam.image_size[1]))
    K1, D1 = np.asarray(cam.left.K, float), np.asarray(cam.left.dist, float)
    K2, D2 = np.asarray(cam.right.K, float), np.asarray(cam.right.dist, float)
    R1, R2, P1, P2, *_ = cv2.stereoRectify(K1, D1, K2, D2, size, np.asarray(cam.R, float),
                                           np.asarray(cam.T, float).reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY)
    left, right = _outline(K1, D1, R1, P1, size), _outline(K2, D2, R2, P2, size)
    # a point at depth Z in the left rectified image appears in the right one shifted by P2[0,3] / Z
    shift = -float(P2[0, 3]) / working_distance_m  # moves the right outline to where the left sees it
    z = np.array([0.0, 0.0, 1.0])
    verg = float(np.degrees(np.arccos(np.clip(z @ (np.asarray(cam.R, float).T @ z), -1.0, 1.0))))
    return CalibrationSummary(size, _camera(K1, size), _camera(K2, size), 1000.0 * cam.baseline, verg,
                              _overlap(left, right, 0.0), working_distance_m, _overlap(left, right, shift),
                              cam.T_world_left is not None)


def summary_text(s: CalibrationSummary) -> str:
    """The summary as a few labelled lines."""
    lines = [f"image size: {s.image_size[0]} x {s.image_size[1]} px"]
    for name, c in (("left", s.left), ("right", s.right)):
        lines.append(f"{name:5s}: fx {c.fx:.2f} px, fy {c.fy:.2f} px, principal point ({c.cx:.2f}, {c.cy:.2f}) px, "
                     f"field of view {c.hfov_deg:.2f} x {c.vfov_deg:.2f} deg (h x v)")
    lines.append(f"baseline: {s.baseline_mm:.3f} mm, optical axes {s.vergence_deg:.3f} deg apart")
    lines.append(f"rectified overlap: {s.rectified_overlap_pct:.1f} % of the left view at infinity, "
                 f"{s.overlap_at_working_distance_pct:.1f} % at {1000 * s.working_distance_m:.0f} mm")
    lines.append(f"world_T_left: {'present' if s.has_world_T_left else 'absent (run wristmark register)'}")
    return "\n".join(lines)
