"""Stereo image synthesis: truth agrees with the pixels, pattern, tip, determinism, settings."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

import cvs.render_arm as render_arm
from cvs.calibration_io import load_calibration
from cvs.camera import scaled_stereo_camera
from cvs.marker import MarkerModel
from cvs.render import StereoFrame, StereoRenderer
from cvs.render_settings import RenderSettings, noise_preset
from cvs.visibility import marker_visible
from models.arm_shape import arm_shape
from models.errors import ConfigError, InputError
from models.robot_params import HOME_PSI, RobotParams

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "camera.yaml"
PSI = np.array(HOME_PSI) + [0.2, 0.0, 0.1, 0.3, 0.0, 0.2]


@pytest.fixture(scope="module")
def half_camera():
    return scaled_stereo_camera(load_calibration(DEFAULT), 0.5)


@pytest.fixture(scope="module")
def frame(half_camera) -> StereoFrame:
    r = StereoRenderer(half_camera, MarkerModel(), noise_preset("default"), seed=5)
    return r.render(arm_shape(RobotParams(), PSI))


def _subpix_errors(img, corners, min_cos: float) -> np.ndarray:
    g = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    p = np.array([c.uv for c in corners if c.cos_view > min_cos], np.float32).reshape(-1, 1, 2)
    assert len(p) >= 3
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    q = cv2.cornerSubPix(g, p.copy(), (5, 5), (-1, -1), crit)
    return np.linalg.norm((q - p).reshape(-1, 2), axis=1)


def test_truth_corners_agree_with_pixels() -> None:
    # Full 1080p, realistic shading and default noise: cornerSubPix started at each visible
    # true corner (cos_view > 0.3) stays within 0.3 px. (At half resolution the shading
    # gradient across oblique corners biases the detector by ~0.3 px; see the flat test.)
    cam = load_calibration(DEFAULT)
    f = StereoRenderer(cam, MarkerModel(), noise_preset("default"), seed=5).render(arm_shape(RobotParams(), PSI))
    for img, cs in ((f.left, f.corners_left), (f.right, f.corners_right)):
        err = _subpix_errors(img, cs, 0.3)
        assert err.max() < 0.3, err


def test_geometry_exact_with_flat_shading(half_camera, monkeypatch) -> None:
    # Without shading gradients the detector's bias vanishes: every corner with cos_view > 0.3
    # must be found within 0.1 px of the truth (pure geometry + distortion + supersampling).
    monkeypatch.setattr(render_arm, "_shade", lambda D, t, N, alb, spec, shin, gain: gain * alb)
    r = StereoRenderer(half_camera, MarkerModel(), noise_preset("none"), seed=1)
    f = r.render(arm_shape(RobotParams(), PSI))
    for img, cs in ((f.left, f.corners_left), (f.right, f.corners_right)):
        err = _subpix_errors(img, cs, 0.3)
        assert err.max() < 0.1, err


def test_patch_colours_follow_the_pattern(half_camera, frame: StereoFrame) -> None:
    m = MarkerModel()
    T_lm = frame.T_left_marker
    T_rl = np.eye(4)
    T_rl[:3, :3], T_rl[:3, 3] = half_camera.R, half_camera.T
    g = cv2.cvtColor(frame.left, cv2.COLOR_BGR2GRAY).astype(float)
    checked = 0
    for k in range(m.columns):
        a = (k + 0.5) * m.beta
        n = T_lm[:3, :3] @ np.array([np.cos(a), np.sin(a), 0.0])
        for z in (0.5 * m.row_height, -0.5 * m.row_height):
            p = T_lm[:3, :3] @ np.array([m.radius * np.cos(a), m.radius * np.sin(a), z]) + T_lm[:3, 3]
            if -(n @ p) / np.linalg.norm(p) < 0.5:
                continue
            u, v = half_camera.project_left(p[None])[0]
            val = g[int(round(v)) - 1 : int(round(v)) + 2, int(round(u)) - 1 : int(round(u)) + 2].mean()
            if m.is_black(a, z):
                assert val < 60, (k, z, val)
            else:
                assert val > 100, (k, z, val)
            checked += 1
    assert checked >= 4


def test_tip_truth(frame: StereoFrame) -> None:
    R, t = frame.T_left_marker[:3, :3], frame.T_left_marker[:3, 3]
    np.testing.assert_allclose(frame.tip_left, t + R @ [0, 0, MarkerModel().tip_offset], atol=1e-12)
    assert 0.05 < frame.tip_left[2] < 0.12  # tens of mm in front of the endoscope


def test_images_shape_and_type(half_camera, frame: StereoFrame) -> None:
    w, h = half_camera.image_size
    for img in (frame.left, frame.right):
        assert img.shape == (h, w, 3) and img.dtype == np.uint8
        assert 20 < img.mean() < 200  # neither black nor blown out
    assert not np.array_equal(frame.left, frame.right)


def test_deterministic_per_seed() -> None:
    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    shape = arm_shape(RobotParams(), HOME_PSI)
    s = RenderSettings(jpeg_quality=80, motion_blur=3.0)
    a = StereoRenderer(cam, MarkerModel(), s, seed=7).render(shape)
    b = StereoRenderer(cam, MarkerModel(), s, seed=7).render(shape)
    c = StereoRenderer(cam, MarkerModel(), s, seed=8).render(shape)
    assert np.array_equal(a.left, b.left) and np.array_equal(a.right, b.right)
    assert not np.array_equal(a.left, c.left)


def test_grayscale_option() -> None:
    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    f = StereoRenderer(cam, MarkerModel(), RenderSettings(colour=False), seed=0).render(
        arm_shape(RobotParams(), HOME_PSI)
    )
    assert f.left.ndim == 2 and f.left.shape == (270, 480)


def test_home_marker_visible() -> None:
    cam = load_calibration(DEFAULT)
    assert marker_visible(cam, MarkerModel(), arm_shape(RobotParams(), HOME_PSI))


def test_settings_validation(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="jpeg_quality"):
        RenderSettings(jpeg_quality=0).validate()
    with pytest.raises(ConfigError, match="supersampling"):
        RenderSettings(supersampling=0).validate()
    with pytest.raises(ConfigError, match="unknown noise preset"):
        noise_preset("loud")
    p = tmp_path / "r.yaml"
    p.write_text("blur_sigma: 1.2\njpeg_quality: 90\n")
    s = RenderSettings.load(p)
    assert s.blur_sigma == 1.2 and s.jpeg_quality == 90
    p.write_text("blur: 1.2\n")
    with pytest.raises(ConfigError, match="unknown key 'blur'"):
        RenderSettings.load(p)


def test_renderer_needs_world_pose(half_camera) -> None:
    from dataclasses import replace

    with pytest.raises(InputError, match="world_T_left"):
        StereoRenderer(replace(half_camera, T_world_left=None), MarkerModel(), RenderSettings())
