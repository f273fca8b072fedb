"""Camera projection and undistortion round trips (default endoscope calibration)."""

from __future__ import annotations

import numpy as np

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.config_files import CONFIG_DIR

DEFAULT = CONFIG_DIR / "camera.yaml"


def test_project_undistort_round_trip() -> None:
    cam = load_calibration(DEFAULT)
    rng = np.random.default_rng(3)
    P = np.column_stack([rng.uniform(-0.04, 0.04, 200), rng.uniform(-0.025, 0.025, 200), rng.uniform(0.06, 0.1, 200)])
    for c in (cam.left, cam.right):
        uv = c.project(P)
        xy = c.undistort(uv)
        np.testing.assert_allclose(xy, P[:, :2] / P[:, 2:], atol=1e-9)


def test_world_left_round_trip_and_right_projection() -> None:
    cam = load_calibration(DEFAULT)
    rng = np.random.default_rng(4)
    Pw = rng.normal(0, 0.05, (50, 3))
    np.testing.assert_allclose(cam.world_from_left(cam.left_from_world(Pw)), Pw, atol=1e-12)
    Pl = np.array([[0.0, 0.0, 0.08]])
    # the right camera sees a point ahead of the left one shifted left by ~f B / z pixels
    du = cam.project_left(Pl)[0, 0] - cam.project_right(Pl)[0, 0]
    assert 60 < du < 120


def test_scaled_camera_scales_pixels() -> None:
    cam = load_calibration(DEFAULT)
    half = scaled_stereo_camera(cam, 0.5)
    P = np.array([[0.01, -0.005, 0.08]])
    uv, uv2 = cam.project_left(P)[0], half.project_left(P)[0]
    np.testing.assert_allclose((uv2 + 0.5), (uv + 0.5) * 0.5, atol=1e-9)
