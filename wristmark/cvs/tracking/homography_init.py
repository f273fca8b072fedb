"""Pose start from one camera: planar homography by DLT (paper eq. 14) and extrinsics (eq. 15).

The marker corners are coplanar (z = 0 in {wm}), so this is Zhang's planar case:
``s [u v 1]^T = A [r1 r2 p] [x y 1]^T``. Points are Hartley-normalised before the SVD for
conditioning. Pixels given here must be *undistorted* (``undistorted_pixels``) so that the
pinhole model with intrinsics A = K holds.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera
from wristmark.models.errors import InputError

Array = NDArray[np.float64]


def undistorted_pixels(camera: Camera, uv_raw: Array) -> Array:
    """Raw (distorted) pixels Nx2 -> undistorted pixels Nx2 of the same camera (P = K)."""
    pts = np.asarray(uv_raw, float).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    K = np.asarray(camera.K, float)
    out = cv2.undistortPoints(pts, K, np.asarray(camera.dist, float), None, None, K, crit)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def _normaliser(p: Array) -> Array:
    """Similarity moving the centroid to 0 and the mean distance to sqrt(2) (Hartley)."""
    c = p.mean(axis=0)
    d = float(np.mean(np.linalg.norm(p - c, axis=1)))
    s = np.sqrt(2.0) / d if d > 0 else 1.0
    return np.array([[s, 0.0, -s * c[0]], [0.0, s, -s * c[1]], [0.0, 0.0, 1.0]])


def homography_dlt(points_plane: Array, uv: Array) -> Array:
    """3x3 homography H with ``[u v 1] ~ H [x y 1]`` by the normalised DLT (eq. 14).

    points_plane: Nx2 plane coordinates [m]; uv: Nx2 undistorted pixels; N >= 4, no three collinear.
    The solution is the right singular vector of the 2N x 9 matrix L for the smallest singular value.
    """
    X = np.asarray(points_plane, float).reshape(-1, 2)
    U = np.asarray(uv, float).reshape(-1, 2)
    n = X.shape[0]
    if n < 4 or U.shape[0] != n:
        raise InputError(f"a homography needs >= 4 matching points, got {n} plane and {U.shape[0]} image points")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(U))):
        raise InputError("homography points must be finite (got NaN or inf)")
    Tx, Tu = _normaliser(X), _normaliser(U)
    Xh = np.column_stack([X, np.ones(n)]) @ Tx.T
    Uh = np.column_stack([U, np.ones(n)]) @ Tu.T
    L = np.zeros((2 * n, 9))
    L[0::2, 0:3] = Xh
    L[0::2, 6:9] = -Uh[:, :1] * Xh
    L[1::2, 3:6] = Xh
    L[1::2, 6:9] = -Uh[:, 1:2] * Xh
    _, _, Vt = np.linalg.svd(L)
    Hn = Vt[-1].reshape(3, 3)
    H = np.linalg.solve(Tu, Hn @ Tx)
    return H / np.linalg.norm(H)


def pose_from_homography(K: Array, H: Array) -> Array:
    """4x4 pose of the plane's frame in the camera frame from H = eta K [r1 r2 p] (eq. 15).

    kappa = 1 / ||K^-1 h1|| (mean of both column norms), r3 = r1 x r2, the rotation projected
    onto SO(3) by SVD, and the sign chosen so that the plane lies in front of the camera (p_z > 0).
    """
    B = np.linalg.solve(np.asarray(K, float), np.asarray(H, float))
    n1, n2 = np.linalg.norm(B[:, 0]), np.linalg.norm(B[:, 1])
    if not (n1 > 0 and n2 > 0):
        raise InputError("degenerate homography: the points must not be collinear")
    kappa = 2.0 / (n1 + n2)
    if B[2, 2] * kappa < 0:
        kappa = -kappa
    r1, r2, p = kappa * B[:, 0], kappa * B[:, 1], kappa * B[:, 2]
    M = np.column_stack([r1, r2, np.cross(r1, r2)])
    u, _, vt = np.linalg.svd(M)
    R = u @ vt
    if np.linalg.det(R) < 0:
        R = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def homography_pose(camera: Camera, points_marker: Array, uv_raw: Array) -> Array:
    """Initial 4x4 pose of the marker frame in this camera's frame from >= 4 corners.

    points_marker: Nx3 corner positions in {wm} with z = 0 [m]; uv_raw: Nx2 raw pixels.
    """
    P = np.asarray(points_marker, float).reshape(-1, 3)
    if np.any(np.abs(P[:, 2]) > 1e-12):
        raise InputError("homography_pose needs coplanar points with z = 0 in the marker frame")
    uv = undistorted_pixels(camera, uv_raw)
    H = homography_dlt(P[:, :2], uv)
    return pose_from_homography(np.asarray(camera.K, float), H)
