"""Which way a fit turns the sleeve: a corner can only be seen on the camera's side of it.

With few corners (three on one ring of a small marker, e.g. at a quarter of the image size) the
stereo fit has two minima that reproject equally well: the true one, and the same arc turned
inside out, its ring centre between the camera and the corners (the corners then lie on the far
side of the sleeve, which hides them). The second minimum was measured 3-9 mm off the true
tip (docs/notes/sleeve-facing.md). :func:`corner_facing` tells the two apart from the fit alone;
:func:`turned_start` is a start pose in the other minimum's basin.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.tracking.rigid_fit import kabsch

Array = NDArray[np.float64]

__all__ = ["corner_facing", "turned_start"]


def corner_facing(T_cam_marker: Array, P_marker: Array, camera_centre: Array) -> Array:
    """Cosine, per corner, between the sleeve's outward normal at the corner and the direction
    from the corner to the camera centre (all in one camera frame [m]; T_cam_marker: 4x4 pose of
    {wm}; P_marker: (n, 3) corners in {wm} on the cylinder about z_wm). Positive: the corner faces
    that camera; negative: it lies on the far side of the sleeve."""
    P = np.asarray(P_marker, float).reshape(-1, 3)
    n = P.copy()
    n[:, 2] = 0.0
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    R, t = T_cam_marker[:3, :3], T_cam_marker[:3, 3]
    X = P @ R.T + t
    d = np.asarray(camera_centre, float).reshape(1, 3) - X
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return np.asarray(np.sum((n @ R.T) * d, axis=1), float)


def turned_start(T_left_marker: Array, P_marker: Array) -> Array:
    """The fit ``T_left_marker`` ({wm} in {ll}) with its sleeve turned the other way in depth: the
    same corners, the sleeve's axis mirrored across the plane through the corners' centroid
    normal to the line of sight (the axis points at the corners' heights, reflected), refit by
    Kabsch; a start pose for the other minimum (corners (n, 3) in {wm})."""
    P = np.asarray(P_marker, float).reshape(-1, 3)
    R, t = T_left_marker[:3, :3], T_left_marker[:3, 3]
    X = P @ R.T + t
    c = X.mean(axis=0)
    v = c / np.linalg.norm(c)
    A = np.zeros_like(P)
    A[:, 2] = P[:, 2]  # the axis point at each corner's height
    AX = A @ R.T + t
    AX_turned = AX + 2.0 * ((c - AX) @ v)[:, None] * v[None, :]
    return kabsch(np.vstack([P, A]), np.vstack([X, AX_turned]))
