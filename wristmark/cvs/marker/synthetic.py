"""A synthetic stereo view of the marker sleeve, drawn with OpenCV polygons (no renderer).

:func:`synthetic_pair` draws the sleeve's white cylinder, its two checker rows and any listed
patches (``MarkerModel.is_black``) as projected quads through the calibration's cameras
(distortion included), for a marker ahead of the left camera with z_wm along +x of {ll} (the arm
entering from the left, as in the default camera's view). It is not the simulated bench's
renderer (no arm, no lighting): it only has to look enough like the marker for every code path
of the tracker to run on it (cvs.tracking.warmup), and it is real pixels, not corners.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]

STEPS_PER_COLUMN = 6  # angular strips per checker column [-]
_SHIFT = 4  # fixed-point bits of the polygon vertices (1/16 px)


def marker_pose_ahead(marker: MarkerModel, camera: StereoCamera, diameter_px: float = 200.0,
                      roll: float = 0.3) -> Array:
    """4x4 pose of {wm} in {ll}: on the optical axis at the depth where the sleeve is about
    ``diameter_px`` wide, z_wm along +x of {ll}, rolled by ``roll`` [rad] about z_wm."""
    f = float(camera.left.K[0][0])
    depth = f * 2.0 * marker.radius / diameter_px
    c, s = np.cos(roll), np.sin(roll)
    base = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # columns x_wm, y_wm, z_wm in {ll}
    T = np.eye(4)
    T[:3, :3] = base @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T[:3, 3] = [0.0, 0.0, depth]
    return T


def _z_breaks(marker: MarkerModel) -> Array:
    z0, z1 = marker.z_extent
    h = marker.row_height
    cuts = {z0, z1, -h, 0.0, h} | {float(v) for p in marker.patches for v in p[2:]}
    return np.array(sorted(v for v in cuts if z0 <= v <= z1))


def _draw_view(marker: MarkerModel, T: Array, project: Callable[[Array], Array], centre: Array,
               size: tuple[int, int], background: int) -> NDArray[np.uint8]:
    w, h = size
    img = np.full((h, w), background, np.uint8)
    n = marker.columns * STEPS_PER_COLUMN
    a = np.linspace(0.0, 2.0 * np.pi, n + 1)
    zs = _z_breaks(marker)
    r, R, t = marker.radius, T[:3, :3], T[:3, 3]
    for a0, a1 in zip(a[:-1], a[1:]):
        am = 0.5 * (a0 + a1)
        normal = R @ np.array([np.cos(am), np.sin(am), 0.0])
        if float(normal @ (R @ np.array([r * np.cos(am), r * np.sin(am), 0.0]) + t - centre)) >= 0:
            continue  # this strip faces away from the camera
        for z0, z1 in zip(zs[:-1], zs[1:]):
            quad = np.array([[r * np.cos(a0), r * np.sin(a0), z0], [r * np.cos(a1), r * np.sin(a1), z0],
                             [r * np.cos(a1), r * np.sin(a1), z1], [r * np.cos(a0), r * np.sin(a0), z1]])
            uv = np.asarray(project(quad @ R.T + t), np.float64)
            colour = 30 if marker.is_black(am, 0.5 * (z0 + z1)) else 225
            pts = np.round(uv * float(1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)
            cv2.fillConvexPoly(img, pts, colour, lineType=cv2.LINE_AA, shift=_SHIFT)
    return np.asarray(cv2.GaussianBlur(img, (0, 0), 0.8), np.uint8)


def synthetic_pair(camera: StereoCamera, marker: MarkerModel, channels: int = 1,
                   T_left_marker: Array | None = None, background: int = 90
                   ) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """(left, right) uint8 views of the calibration's size showing the marker at
    ``T_left_marker`` (default :func:`marker_pose_ahead`); grey (h, w), or BGR (h, w, 3) with
    ``channels=3``."""
    T = marker_pose_ahead(marker, camera) if T_left_marker is None else np.asarray(T_left_marker, float)
    T_rl = np.eye(4)
    T_rl[:3, :3], T_rl[:3, 3] = camera.R, camera.T
    right_centre = np.asarray(np.linalg.inv(T_rl)[:3, 3], np.float64)  # the right camera's centre in {ll}
    views = [_draw_view(marker, T, camera.project_left, np.zeros(3), camera.image_size, background),
             _draw_view(marker, T, camera.project_right, right_centre, camera.image_size, background)]
    if channels == 3:
        views = [np.asarray(cv2.cvtColor(v, cv2.COLOR_GRAY2BGR), np.uint8) for v in views]
    return views[0], views[1]
