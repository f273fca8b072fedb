"""Homography start (paper eq. 14-15): exact recovery of a known planar pose, and its errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wristmark.cvs.camera import Camera
from wristmark.cvs.tracking.homography_init import (
    homography_dlt,
    homography_pose,
    pose_from_homography,
    undistorted_pixels,
)
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

K = np.array([[1380.0, 0, 959.5], [0, 1380.0, 539.5], [0, 0, 1]])
CAM = Camera(K, np.array([-0.25, 0.08, 0.001, -0.0005, 0.0]))


def _pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    # tilted up to ~70 deg from facing the camera (the plane's z axis points away from it)
    T[:3, :3] = Rotation.from_rotvec(rng.normal(0, 0.6, 3)).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(0.06, 0.12)]
    return T


@pytest.mark.parametrize("seed", range(5))
def test_recovers_pose_from_exact_projections(seed: int) -> None:
    rng = np.random.default_rng(seed)
    T = _pose(rng)
    P = MarkerModel().corners()[:6]
    uv = CAM.project(P @ T[:3, :3].T + T[:3, 3])
    T_est = homography_pose(CAM, P, uv)
    assert np.allclose(T_est, T, atol=1e-9)


def test_dlt_matches_known_homography() -> None:
    H = np.array([[1.2, 0.1, 30.0], [-0.2, 0.9, 10.0], [1e-3, 2e-3, 1.0]])
    X = np.random.default_rng(1).uniform(-5, 5, (7, 2))
    U = np.column_stack([X, np.ones(7)]) @ H.T
    U = U[:, :2] / U[:, 2:]
    H_est = homography_dlt(X, U)
    assert np.allclose(H_est / H_est[2, 2], H / H[2, 2], atol=1e-9)


def test_pose_sign_puts_plane_in_front() -> None:
    T = np.eye(4)
    T[:3, 3] = [0.001, -0.002, 0.08]
    H = K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]])
    for s in (1.0, -3.0):
        assert np.allclose(pose_from_homography(K, s * H), T, atol=1e-12)


def test_undistorted_pixels_round_trip() -> None:
    P = np.array([[0.01, -0.005, 0.08], [-0.02, 0.01, 0.09]])
    ideal = (P / P[:, 2:]) @ K.T
    assert np.allclose(undistorted_pixels(CAM, CAM.project(P)), ideal[:, :2], atol=1e-6)


def test_errors() -> None:
    with pytest.raises(InputError, match=">= 4"):
        homography_dlt(np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(InputError, match="finite"):
        homography_dlt(np.full((4, 2), np.nan), np.zeros((4, 2)))
    with pytest.raises(InputError, match="z = 0"):
        homography_pose(CAM, np.ones((4, 3)), np.zeros((4, 2)))
