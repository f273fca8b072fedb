"""The latest left camera frame in the 3D view: an image pane at the left frustum's far end.

The loop side (:func:`frame_png`) shrinks the left image, draws the detected corners on it
and encodes it as PNG; the drawing process (:func:`show_frame`) puts it as the texture of a
thin box spanning the frustum's far rectangle, in the left camera frame {ll}, facing the
camera (pinhole; distortion ignored, as for the frustum lines).
"""

from __future__ import annotations

import cv2
import meshcat
import meshcat.geometry as mg
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.viz.shapes import FRUSTUM_DEPTH

PANE_NODE = "endoscope/left_image"  # under the scene's root
PANE_WIDTH_PX = 384  # [px] width of the image sent to the browser
CORNER_COLOR = (0, 255, 255)  # BGR: yellow circles on the detected corners
MIN_SIDE_PX = 16  # frames smaller than this (the truth-noise option's empty frames) are not shown


def frame_png(left: NDArray[np.uint8], corners_left: NDArray[np.float64] | None = None,
              width: int = PANE_WIDTH_PX) -> bytes | None:
    """PNG of the left image shrunk to ``width`` px with the corners (raw pixels (N, 2)) drawn
    as circles; None for an image too small to show."""
    h, w = left.shape[:2]
    if min(h, w) < MIN_SIDE_PX:
        return None
    scale = min(1.0, width / w)
    img = cv2.resize(left, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    for u, v in np.asarray(corners_left if corners_left is not None else np.zeros((0, 2)), float).reshape(-1, 2):
        if np.isfinite(u) and np.isfinite(v):
            cv2.circle(img, (round(u * scale), round(v * scale)), 4, CORNER_COLOR, 1, cv2.LINE_AA)
    ok, buf = cv2.imencode(".png", img)
    return buf.tobytes() if ok else None


def pane_pose(camera: StereoCamera, depth: float = FRUSTUM_DEPTH) -> tuple[tuple[float, float], NDArray[np.float64]]:
    """(width, height) [m] of the far rectangle of the left frustum at ``depth`` and the 4x4 pose
    in {ll} of a pane on it whose +z faces the camera and whose +y is the image's up."""
    K = np.asarray(camera.left.K, float)
    w, h = camera.image_size
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = [depth * ((w - 1) / 2 - cx) / fx, depth * ((h - 1) / 2 - cy) / fy, depth]
    return (depth * w / fx, depth * h / fy), T


def show_frame(vis: meshcat.Visualizer, root: str, camera: StereoCamera, png: bytes) -> None:
    """Put the PNG on the pane under ``root``'s endoscope node (which sits at {ll})."""
    (width, height), T = pane_pose(camera)
    node = vis[f"{root}/{PANE_NODE}"]
    material = mg.MeshBasicMaterial(map=mg.ImageTexture(image=mg.PngImage(png)))
    node.set_object(mg.Box([width, height, 1e-5]), material)
    node.set_transform(T)
