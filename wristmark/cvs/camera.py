"""Pinhole cameras with OpenCV distortion and the stereo pair (OpenCV conventions).

Image axes: x right, y down, z along the optical axis; pixel (0, 0) is the centre of the
top-left pixel. Stereo: X_right = R X_left + T (as ``cv2.stereoCalibrate``). {ll} is the left
camera frame. ``T_world_left`` is the pose of {ll} in {w} (4x4, metres) when known.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import ConfigError, InputError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Camera:
    """Intrinsics K (3x3, px) and distortion [k1, k2, p1, p2, k3] of one camera."""

    K: Array
    dist: Array

    def validate(self, name: str = "camera") -> None:
        """Raise ConfigError on a malformed K or dist."""
        K = np.asarray(self.K, float)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)):
            raise ConfigError(f"'{name}.K' must be a finite 3x3 matrix, got shape {K.shape}")
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ConfigError(f"'{name}.K' focal lengths must be > 0, got fx={K[0,0]}, fy={K[1,1]}")
        if not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:
            raise ConfigError(f"'{name}.K' must be upper-triangular with last row [0, 0, 1]")
        d = np.asarray(self.dist, float)
        if d.shape != (5,) or not np.all(np.isfinite(d)):
            raise ConfigError(f"'{name}.dist' must be 5 finite numbers [k1,k2,p1,p2,k3], got {d.shape}")

    def project(self, points_cam: Array) -> Array:
        """Project Nx3 points given in this camera's frame [m] to raw (distorted) pixels Nx2."""
        P = np.ascontiguousarray(np.asarray(points_cam, float).reshape(-1, 3))
        uv, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), self.K, self.dist)
        return np.asarray(uv, dtype=np.float64).reshape(-1, 2)

    def undistort(self, uv: Array) -> Array:
        """Raw pixels Nx2 -> normalized image coordinates Nx2 (x/z, y/z), distortion removed."""
        pts = np.asarray(uv, float).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
        out = cv2.undistortPoints(pts, self.K, self.dist, None, None, None, crit)
        return np.asarray(out, dtype=np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class StereoCamera:
    """A calibrated stereo pair: left/right cameras, X_right = R X_left + T, image size (w, h)."""

    image_size: tuple[int, int]
    left: Camera
    right: Camera
    R: Array
    T: Array
    T_world_left: Array | None = field(default=None)

    def validate(self) -> None:
        """Raise ConfigError naming the first malformed entry."""
        w, h = self.image_size
        if w <= 0 or h <= 0:
            raise ConfigError(f"'image_size' must be positive [width, height], got {list(self.image_size)}")
        self.left.validate("left")
        self.right.validate("right")
        R = np.asarray(self.R, float)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise ConfigError(f"'R' must be a finite 3x3 matrix, got shape {R.shape}")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ConfigError("'R' must be a proper rotation (orthonormal, det +1)")
        T = np.asarray(self.T, float)
        if T.shape != (3,) or not np.all(np.isfinite(T)) or np.linalg.norm(T) == 0:
            raise ConfigError(f"'T' must be a non-zero 3-vector in metres, got {T.tolist()}")
        if self.T_world_left is not None:
            W = np.asarray(self.T_world_left, float)
            if W.shape != (4, 4) or not np.allclose(W[3], [0, 0, 0, 1]):
                raise ConfigError("'world_T_left' must be a 4x4 homogeneous transform")
            Rw = W[:3, :3]
            if not np.allclose(Rw @ Rw.T, np.eye(3), atol=1e-6) or np.linalg.det(Rw) < 0:
                raise ConfigError("'world_T_left' rotation must be proper (orthonormal, det +1)")

    @property
    def baseline(self) -> float:
        """Distance between the two optical centres [m]."""
        return float(np.linalg.norm(self.T))

    def right_from_left(self, points_left: Array) -> Array:
        """Nx3 points from {ll} to the right camera frame [m]."""
        return np.asarray(points_left, float).reshape(-1, 3) @ np.asarray(self.R).T + self.T

    def project_left(self, points_left: Array) -> Array:
        """Nx3 points in {ll} [m] -> raw left pixels Nx2."""
        return self.left.project(points_left)

    def project_right(self, points_left: Array) -> Array:
        """Nx3 points in {ll} [m] -> raw right pixels Nx2."""
        return self.right.project(self.right_from_left(points_left))

    def left_from_world(self, points_world: Array) -> Array:
        """Nx3 points from {w} to {ll} [m]; needs T_world_left."""
        if self.T_world_left is None:
            raise InputError("this calibration has no 'world_T_left': the world frame is unknown")
        W = np.asarray(self.T_world_left)
        return (np.asarray(points_world, float).reshape(-1, 3) - W[:3, 3]) @ W[:3, :3]

    def world_from_left(self, points_left: Array) -> Array:
        """Nx3 points from {ll} to {w} [m]; needs T_world_left."""
        if self.T_world_left is None:
            raise InputError("this calibration has no 'world_T_left': the world frame is unknown")
        W = np.asarray(self.T_world_left)
        return np.asarray(points_left, float).reshape(-1, 3) @ W[:3, :3].T + W[:3, 3]


def scaled_stereo_camera(cam: StereoCamera, factor: float) -> StereoCamera:
    """The same stereo endoscope imaged at ``factor`` times the resolution (for fast tests).

    Focal lengths and principal points scale with the image (pixel-centre convention kept);
    distortion, R, T and T_world_left are unchanged.
    """
    if not factor > 0:
        raise InputError(f"scale factor must be > 0, got {factor}")

    def sc(c: Camera) -> Camera:
        K = np.array(c.K, float).copy()
        K[0, 0] *= factor
        K[1, 1] *= factor
        K[0, 1] *= factor
        K[0, 2] = (K[0, 2] + 0.5) * factor - 0.5
        K[1, 2] = (K[1, 2] + 0.5) * factor - 0.5
        return Camera(K, np.array(c.dist, float))

    w, h = cam.image_size
    size = (int(round(w * factor)), int(round(h * factor)))
    return StereoCamera(size, sc(cam.left), sc(cam.right), cam.R, cam.T, cam.T_world_left)
