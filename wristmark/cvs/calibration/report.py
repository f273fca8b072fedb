"""``wristmark calibrate --report DIR``: report.md with per-view errors, a coverage picture per
camera (where the corners of the used views fell) and the rectified pair with epipolar lines."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.calibration.stereo import StereoCalibration, StereoView
from wristmark.cvs.camera import StereoCamera


def coverage_image(views: list[StereoView], side: str, size: tuple[int, int],
                   used: set[str]) -> NDArray[np.uint8]:
    """A dark picture of the image area with every found corner drawn: used views in colour,
    dropped ones grey; the board outline of each used view joins its corners' hull."""
    w, h = size
    img = np.full((h, w, 3), 30, np.uint8)
    r = max(2, round(min(w, h) / 240))
    for k, v in enumerate(views):
        bv = getattr(v, side)
        if bv is None:
            continue
        hue = int(180 * k / max(1, len(views)))
        hsv = np.array([[[hue, 220, 255]]], np.uint8)
        colour = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0].tolist() if v.name in used else [120, 120, 120]
        pts = np.asarray(bv.image_points, np.float32)
        cv2.polylines(img, [cv2.convexHull(pts).astype(np.int32)], True, colour, 1, cv2.LINE_AA)
        for u, vv in pts:
            cv2.circle(img, (int(round(u)), int(round(vv))), r, colour, -1, cv2.LINE_AA)
    return img


def rectified_pair(cam: StereoCamera, left: NDArray[np.uint8], right: NDArray[np.uint8],
                   lines: int = 16) -> NDArray[np.uint8]:
    """Both images rectified (cv2.stereoRectify, alpha 0) side by side with horizontal epipolar
    lines: a good calibration puts each scene point on the same line in both halves."""
    size = (int(cam.image_size[0]), int(cam.image_size[1]))
    R1, R2, P1, P2, *_ = cv2.stereoRectify(cam.left.K, cam.left.dist, cam.right.K, cam.right.dist, size,
                                           np.asarray(cam.R, float), np.asarray(cam.T, float).reshape(3, 1),
                                           alpha=0.0)
    out = []
    for c, R, P, img in ((cam.left, R1, P1, left), (cam.right, R2, P2, right)):
        mx, my = cv2.initUndistortRectifyMap(c.K, c.dist, R, P, size, cv2.CV_32FC1)
        im = cv2.remap(img, mx, my, cv2.INTER_LINEAR)
        out.append(cv2.cvtColor(im, cv2.COLOR_GRAY2BGR) if im.ndim == 2 else im)
    pair = np.ascontiguousarray(np.hstack(out), np.uint8)
    for y in np.linspace(0, size[1] - 1, lines + 2)[1:-1]:
        cv2.line(pair, (0, int(y)), (pair.shape[1] - 1, int(y)), (0, 255, 0), 1, cv2.LINE_AA)
    return pair


def _px(x: float) -> str:
    return "" if np.isnan(x) else f"{x:.3f}"


def write_report(out_dir: Path, result: StereoCalibration, views: list[StereoView], board: str,
                 example: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None) -> Path:
    """Write report.md and its PNG files in ``out_dir``; returns the report's path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    cam = result.camera
    used = {v.name for v in result.views if v.used}
    for side in ("left", "right"):
        cv2.imwrite(str(out_dir / f"coverage_{side}.png"), coverage_image(views, side, cam.image_size, used))
    lines = [
        "# Stereo calibration report", "",
        f"Board `{board}`; {len(used)} of {len(views)} views used. Stereo RMS reprojection error "
        f"{result.rms_px:.3f} px (each camera alone: left {result.mono_rms_px[0]:.3f} px, right "
        f"{result.mono_rms_px[1]:.3f} px).", "",
        f"Left: fx {cam.left.K[0, 0]:.2f} px, fy {cam.left.K[1, 1]:.2f} px, principal point "
        f"({cam.left.K[0, 2]:.2f}, {cam.left.K[1, 2]:.2f}) px. Right: fx {cam.right.K[0, 0]:.2f} px, fy "
        f"{cam.right.K[1, 1]:.2f} px, principal point ({cam.right.K[0, 2]:.2f}, {cam.right.K[1, 2]:.2f}) px. "
        f"Baseline {1000 * cam.baseline:.3f} mm.", "",
        "## Per-view errors", "", "| view | left RMS [px] | right RMS [px] | used | why not |", "|---|---|---|---|---|",
    ]
    for v in result.views:
        lines.append(f"| {v.name} | {_px(v.left_px)} | {_px(v.right_px)} | {'yes' if v.used else 'no'} | {v.reason} |")
    lines += ["", "## Coverage (where the corners fell; grey: dropped views)", "",
              "![left](coverage_left.png) ![right](coverage_right.png)", ""]
    if example is not None:
        cv2.imwrite(str(out_dir / "rectified_pair.png"), rectified_pair(cam, *example))
        lines += ["## Rectified pair with epipolar lines", "",
                  "Corresponding points must lie on the same green line in both halves.", "",
                  "![rectified](rectified_pair.png)", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(lines))
    return path
