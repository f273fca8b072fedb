"""Where one view's corners can appear in the other view of a calibrated stereo pair: the box
around their epipolar segments (each corner's ray between two depths, projected), for searching
the other view when only one view's chain was found (MarkerTracker's gap retry)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera

Array = NDArray[np.float64]
__all__ = ["epipolar_box"]
MAX_TAN = 1.5  # points further off the other camera's axis (x/z, y/z) are left out: its distortion model diverges


def epipolar_box(camera: StereoCamera, uv: Array, from_right: bool, depths_m: tuple[float, float],
                 margin_px: float, steps: int = 16) -> tuple[int, int, int, int] | None:
    """The box (x, y, w, h) [px] of the other view, clipped to the image, holding the projections
    of the rays through the raw pixels ``uv`` (N, 2) of the right view (``from_right``) or the left
    one, at ``steps`` depths from depths_m[0] to depths_m[1] [m] along each camera's optical axis,
    grown by ``margin_px``; None when no point projects in front of the other camera or the box
    leaves the image."""
    cam = camera.right if from_right else camera.left
    xy = cam.undistort(np.asarray(uv, float).reshape(-1, 2))
    z = np.geomspace(depths_m[0], depths_m[1], steps)
    P = np.concatenate([np.column_stack([xy * d, np.full(len(xy), d)]) for d in z])  # in the seeing camera
    R, T = np.asarray(camera.R, float), np.asarray(camera.T, float)
    P_other = (P - T) @ R if from_right else P @ R.T + T  # X_right = R X_left + T
    with np.errstate(divide="ignore", invalid="ignore"):  # in front, within the lens's polynomial's reach
        seen = (P_other[:, 2] > 1e-4) & (np.abs(P_other[:, :2] / P_other[:, 2:]).max(axis=1) <= MAX_TAN)
    px = camera.project_left(P_other[seen]) if from_right else camera.project_right(P[seen])
    if px.size == 0 or not np.all(np.isfinite(px)):
        return None
    w, h = camera.image_size
    x0, y0 = np.floor(px.min(axis=0) - margin_px)
    x1, y1 = np.ceil(px.max(axis=0) + margin_px)
    x0, y0, x1, y1 = max(int(x0), 0), max(int(y0), 0), min(int(x1), w), min(int(y1), h)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return x0, y0, x1 - x0, y1 - y0
