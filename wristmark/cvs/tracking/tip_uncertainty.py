"""How well a stereo fit's corners determine the tip: its standard deviation from the fit's
reprojection Jacobian at a given corner noise (first order).

A fit on three corners of one ring per view (a small or steeply seen sleeve) reprojects to a few
hundredths of a pixel and can still put the tip 2-9 mm off: the ring's tilt is barely seen, and
the tip lies ``tip_offset`` beyond the ring. Its tip sigma is then 2-9 mm at 0.3 px of corner
noise, where well seen sleeves give 0.1-0.3 mm (docs/notes/steep-views.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera

Array = NDArray[np.float64]

__all__ = ["tip_sigma"]


def _skew(v: Array) -> Array:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def tip_sigma(camera: StereoCamera, T_left_marker: Array, points_left: Array, points_right: Array,
              tips_marker: Array, corner_sigma_px: float) -> float:
    """The largest 3D standard deviation [m] of the points ``tips_marker`` (K, 3) in {wm} [m]
    (e.g. the tip at either end of the sleeve) for the pose ``T_left_marker`` of {wm} in {ll}
    fitted to the corners ``points_left`` / ``points_right`` (N, 3) in {wm} [m] seen by each
    camera, each pixel coordinate with noise ``corner_sigma_px`` [px]; inf when the corners do
    not determine the pose."""
    T = np.asarray(T_left_marker, float)
    R, t = T[:3, :3], T[:3, 3]
    Pl = np.asarray(points_left, float).reshape(-1, 3)
    Pr = np.asarray(points_right, float).reshape(-1, 3)

    # the pose and its six perturbations (R exp([w]x), t + v), projected in one call per camera
    h_rot, h_tr = 1e-6, 1e-7  # [rad], [m]
    poses = [(R, t)]
    for i in range(3):
        w = np.zeros(3)
        w[i] = h_rot
        poses.append((R @ (np.eye(3) + _skew(w)), t))  # first order in h_rot: exp([w]x) ~ I + [w]x
    for i in range(3):
        v = np.zeros(3)
        v[i] = h_tr
        poses.append((R, t + v))
    k = len(poses)
    views = [(camera.project_left, Pl), (camera.project_right, Pr)]
    uv = np.hstack([project(np.concatenate([P @ Rx.T + tx for Rx, tx in poses])).reshape(k, -1) if len(P)
                    else np.zeros((k, 0)) for project, P in views])
    if uv.shape[1] < 6:
        return float("inf")
    steps = np.array([h_rot] * 3 + [h_tr] * 3)
    J = ((uv[1:] - uv[0]) / steps[:, None]).T  # (2 N, 6)
    JtJ = J.T @ J
    if not np.all(np.isfinite(JtJ)) or np.linalg.cond(JtJ) > 1e14:
        return float("inf")
    C = corner_sigma_px**2 * np.linalg.inv(JtJ)  # pose covariance: (rotation vector, translation)
    worst = 0.0
    for c in np.asarray(tips_marker, float).reshape(-1, 3):
        Jt = np.hstack([-R @ _skew(c), np.eye(3)])  # d tip / d (w, v) for R exp([w]x), t + v
        worst = max(worst, float(np.sqrt(max(np.trace(Jt @ C @ Jt.T), 0.0))))
    return worst
