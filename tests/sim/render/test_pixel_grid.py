"""sim.render.pixel_grid: the renderer's undistorted pixel grid is OpenCV's, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.cvs.camera import Camera
from wristmark.sim.render.pixel_grid import undistorted_grid
from wristmark.sim.setup import load_setup

SETUP_CAMERA = load_setup().true_camera
K = np.array([[1210.0, 0.4, 955.0], [0.0, 1204.0, 541.0], [0.0, 0.0, 1.0]])  # with a skew (OpenCV ignores it)


@pytest.mark.parametrize("camera", [
    SETUP_CAMERA.left,
    SETUP_CAMERA.right,
    Camera(K, np.array([-0.31, 0.12, 0.0021, -0.0013, -0.02])),  # tangential and k3 terms
    Camera(K, np.array([0.05, -0.4, 0.0, 0.0, 0.9])),  # pincushion
    Camera(K, np.zeros(5)),
], ids=["left", "right", "tangential", "pincushion", "none"])
def test_the_grid_is_cv2_undistort_points_bit_for_bit(camera: Camera) -> None:
    # every 7th row and column of a padded 1080p grid, corners and edges included (where the
    # iteration works hardest; the renderer asks for nothing beyond the 1 px border)
    u0, v0, w, h = -1.0, -1.0, 1922, 1082
    grid = undistorted_grid(camera, u0, v0, w, h)
    assert grid.shape == (h, w, 2) and grid.dtype == np.float64
    rows, cols = np.r_[np.arange(0, h, 7), h - 1], np.r_[np.arange(0, w, 7), w - 1]
    u, v = np.meshgrid(u0 + cols, v0 + rows)
    expected = camera.undistort(np.column_stack([u.ravel(), v.ravel()])).reshape(len(rows), len(cols), 2)
    np.testing.assert_array_equal(grid[np.ix_(rows, cols)], expected)
