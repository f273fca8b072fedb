"""Is the wrist marker seen by both cameras of a calibrated pair, at a given pose in {ll}?"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]


def marker_in_view(camera: StereoCamera, marker: MarkerModel, T_left_marker: Array, min_corners: int = 3,
                   margin_px: float = 20.0, min_cos: float = 0.3) -> bool:
    """True if the whole sleeve (pose of {wm} in {ll}, 4x4 [m]) projects inside both images
    (``margin_px`` from the border), at least 20 mm in front, and each camera sees at least
    ``min_corners`` corners facing it (cosine between normal and view direction > ``min_cos``)."""
    T_rl = np.eye(4)
    T_rl[:3, :3], T_rl[:3, 3] = camera.R, camera.T
    w, h = camera.image_size
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)]) * marker.radius
    rim = np.vstack([ring + [0, 0, marker.row_height], ring - [0, 0, marker.row_height]])
    for cam, T in ((camera.left, T_left_marker), (camera.right, T_rl @ T_left_marker)):
        P = rim @ T[:3, :3].T + T[:3, 3]
        if np.any(P[:, 2] < 0.02):
            return False
        uv = cam.project(P)
        if np.any(uv < margin_px) or np.any(uv[:, 0] > w - 1 - margin_px) or np.any(uv[:, 1] > h - 1 - margin_px):
            return False
        C = marker.corners() @ T[:3, :3].T + T[:3, 3]
        N = marker.corner_normals() @ T[:3, :3].T
        cos = -(N * C).sum(axis=1) / np.linalg.norm(C, axis=1)
        if int(np.sum(cos > min_cos)) < min_corners:
            return False
    return True
