"""Stereo image synthesis: truth agrees with the pixels, pattern, tip, determinism, settings."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import RenderSettings, noise_preset
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer
from wristmark.sim.visibility import marker_visible

DEFAULT = CONFIG_DIR / "camera.yaml"
PSI = np.array(HOME_PSI) + [0.2, 0.0, 0.1, 0.3, 0.0, 0.2]


@pytest.fixture(scope="module")
def half_camera():
    return scaled_stereo_camera(load_calibration(DEFAULT), 0.5)


@pytest.fixture(scope="module")
def frame(half_camera) -> RenderedPair:
    r = StereoRenderer(half_camera, MarkerModel(), noise_preset("default"), seed=5)
    return r.render(arm_shape(RobotParams(), PSI))


def _subpix_errors(img, corners, min_cos: float) -> np.ndarray:
    g = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    p = np.array([c.uv for c in corners if c.cos_view > min_cos], np.float32).reshape(-1, 1, 2)
    assert len(p) >= 3
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    q = cv2.cornerSubPix(g, p.copy(), (5, 5), (-1, -1), crit)
    return np.linalg.norm((q - p).reshape(-1, 2), axis=1)


@pytest.mark.slow
def test_truth_corners_agree_with_pixels() -> None:
    # Full 1080p, realistic shading and default noise: cornerSubPix started at each visible
    # true corner (cos_view > 0.3) stays within 0.3 px. (At half resolution the shading
    # gradient across oblique corners biases the detector by ~0.3 px; see the flat test.)
    cam = load_calibration(DEFAULT)
    f = StereoRenderer(cam, MarkerModel(), noise_preset("default"), seed=5).render(arm_shape(RobotParams(), PSI))
    for img, cs in ((f.left, f.corners_left), (f.right, f.corners_right)):
        err = _subpix_errors(img, cs, 0.3)
        assert err.max() < 0.3, err


def test_geometry_exact_with_flat_shading(half_camera) -> None:
    # Without shading gradients the detector's bias vanishes: every corner with cos_view > 0.3
    # must be found within 0.1 px of the truth (pure geometry + distortion + supersampling).
    r = StereoRenderer(half_camera, MarkerModel(), noise_preset("none", shading="flat"), seed=1)
    f = r.render(arm_shape(RobotParams(), PSI))
    for img, cs in ((f.left, f.corners_left), (f.right, f.corners_right)):
        err = _subpix_errors(img, cs, 0.3)
        assert err.max() < 0.1, err


def test_patch_colours_follow_the_pattern(half_camera, frame: RenderedPair) -> None:
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


def test_tip_truth(frame: RenderedPair) -> None:
    R, t = frame.T_left_marker[:3, :3], frame.T_left_marker[:3, 3]
    np.testing.assert_allclose(frame.tip_left, t + R @ [0, 0, MarkerModel().tip_offset], atol=1e-12)
    assert 0.05 < frame.tip_left[2] < 0.12  # tens of mm in front of the endoscope


def test_images_shape_and_type(half_camera, frame: RenderedPair) -> None:
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


# --- incremental optics, adaptive supersampling and the sensor ----------------------------


@pytest.mark.parametrize("settings", [noise_preset("default"), RenderSettings(colour=False, blur_sigma=1.4)])
def test_incremental_optics_equal_full_frame(half_camera, settings) -> None:
    # Only the arm's box is blurred each frame, over the cached optics of the background: the
    # signal before noise must equal running vignetting + blur (+ grey) over the whole frame.
    r = StereoRenderer(half_camera, MarkerModel(), settings, seed=3)
    for shape in (arm_shape(RobotParams(), PSI), arm_shape(RobotParams(), HOME_PSI)):
        for cam in (0, 1):
            inc, full = r.signal(shape, cam), r.signal(shape, cam, incremental=False)
            assert inc.shape == full.shape == (540, 960, 3)[: inc.ndim]
            np.testing.assert_allclose(inc, full, rtol=0, atol=1e-4)
            assert np.abs(full - r._bg_signal[cam]).max() > 50  # the arm is really there


@pytest.mark.slow
def test_adaptive_supersampling_matches_full(half_camera) -> None:
    # Supersampling only where a pixel's neighbourhood changes surface or curves its shading
    # leaves the radiance within 0.1 grey levels of supersampling every pixel, with far fewer rays.
    from wristmark.sim.render.arm import plan_arm, render_arm
    from wristmark.sim.render.stereo_renderer import EXPOSURE, arm_primitives

    raw = dict(read_noise=0.0, shot_gain=0.0, blur_sigma=0.0, vignetting=0.0)
    a = StereoRenderer(half_camera, MarkerModel(), RenderSettings(**raw), seed=0)
    b = StereoRenderer(half_camera, MarkerModel(), RenderSettings(adaptive_supersampling=False, **raw), seed=0)
    shape = arm_shape(RobotParams(), PSI)
    for cam in (0, 1):
        np.testing.assert_allclose(a.signal(shape, cam), b.signal(shape, cam), rtol=0, atol=0.1)
    caps, sleeve = arm_primitives(shape, MarkerModel(), a.T_left_world)
    plan = plan_arm(a._maps[0], caps, sleeve, 3, 3)  # the whole arm at 3 x 3
    assert plan is not None
    img = a._bg[0].copy()
    n_ada = render_arm(a._maps[0], plan, EXPOSURE, img, (0, 0), adaptive=True)
    n_full = render_arm(a._maps[0], plan, EXPOSURE, img.copy(), (0, 0), adaptive=False)
    assert n_ada < 0.5 * n_full


@pytest.mark.slow
def test_noise_fresh_every_frame_with_the_sensor_statistics(half_camera) -> None:
    # Two renders of the same arm differ by noise alone: zero mean, and variance
    # 2 (shot_gain s + read^2) + 2/12 (quantisation) per pixel and channel.
    st = noise_preset("default")
    r = StereoRenderer(half_camera, MarkerModel(), st, seed=4)
    shape = arm_shape(RobotParams(), PSI)
    f1, f2 = r.render(shape), r.render(shape)
    s = r.signal(shape, 0)
    ok = (s > 5) & (s < 240)  # away from saturation
    var = 2 * (st.shot_gain * s + st.read_noise**2) + 2 / 12
    z = (f1.left.astype(float) - f2.left.astype(float))[ok] / np.sqrt(var[ok])
    assert abs(z.mean()) < 0.01 and abs(z.std() - 1) < 0.03, (z.mean(), z.std())
    assert not np.array_equal(f1.right, f2.right)
    g = StereoRenderer(half_camera, MarkerModel(), st, seed=4).render(shape)  # same seed, same bytes
    assert np.array_equal(g.left, f1.left) and np.array_equal(g.right, f1.right)


def test_sensor_noise_does_not_depend_on_the_patch() -> None:
    # The noise of a pixel depends on (key, pixel, channel) only: replacing a region by a patch
    # gives the bytes of rendering the pasted frame whole.
    from wristmark.sim.render.sensor import normal_table, sensor_image

    rng = np.random.default_rng(0)
    st = noise_preset("default")
    base = (rng.random((61, 83, 3)) * 260 - 2).astype(np.float32)
    patch = (rng.random((17, 29, 3)) * 260 - 2).astype(np.float32)
    whole = base.copy()
    whole[20:37, 5:34] = patch
    a = sensor_image(whole, st, 12345)
    assert np.array_equal(a, sensor_image(base, st, 12345, patch, (5, 20)))
    assert not np.array_equal(a, sensor_image(whole, st, 12346))
    quiet = sensor_image(whole, noise_preset("none"), 1)
    np.testing.assert_array_equal(quiet, np.clip(np.floor(whole + 0.5), 0, 255).astype(np.uint8))
    t = normal_table().astype(float)
    assert len(t) == 2**16 and np.all(np.diff(t) > 0)
    assert abs(t.mean()) < 1e-6 and abs((t**2).mean() - 1) < 1e-6 and 4.3 < t.max() < 4.4


def test_shading_setting_validated() -> None:
    with pytest.raises(ConfigError, match="shading"):
        RenderSettings(shading="glossy").validate()


def test_render_stage_inputs_validated() -> None:
    from wristmark.sim.render.optics import optics_signal_box
    from wristmark.sim.render.sensor import sensor_image

    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    r = StereoRenderer(cam, MarkerModel(), RenderSettings(), seed=0)
    with pytest.raises(InputError, match="cam must be 0"):
        r.signal(arm_shape(RobotParams(), HOME_PSI), cam=2)
    img = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(InputError, match="does not fit"):
        sensor_image(img, RenderSettings(), 0, np.zeros((9, 2, 3), np.float32))
    with pytest.raises(InputError, match="motion blur"):
        optics_signal_box(img, (0, 0), (2, 2, 4, 4), img, RenderSettings(motion_blur=3.0))
    with pytest.raises(InputError, match="patch must cover"):
        optics_signal_box(img[:4], (0, 0), (2, 2, 4, 4), img, RenderSettings())
    with pytest.raises(InputError, match="out must be"):
        sensor_image(img, RenderSettings(), 0, out=np.zeros((8, 16, 3), np.uint8)[:, ::2])


# --- the faster pipeline (issue 11 b): same bytes as the straightforward one ------------------


def _reference_sensor(signal: np.ndarray, st: RenderSettings, key: int) -> np.ndarray:
    """The sensor of the module docstring of sim.render.sensor, written again in numpy (float32)."""
    from wristmark.sim.render.sensor import normal_table

    n = signal.size
    k = np.arange((n + 3) // 4, dtype=np.uint64) + np.uint64(1)
    with np.errstate(over="ignore"):
        z = np.uint64(key) + k * np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    lane = np.arange(n, dtype=np.uint64) & np.uint64(3)
    field = (z[np.arange(n) // 4] >> (np.uint64(16) * lane)) & np.uint64(0xFFFF)
    noisy = st.shot_gain > 0 or st.read_noise > 0
    g = normal_table()[field.astype(np.int64)] if noisy else np.zeros(n, np.float32)
    s = signal.astype(np.float32).ravel()
    sd = np.sqrt(np.maximum(s, np.float32(0)) * np.float32(st.shot_gain) + np.float32(st.read_noise**2))
    x = np.minimum(np.maximum(s + sd * g + np.float32(0.5), np.float32(0)), np.float32(255))
    return x.astype(np.uint8).reshape(signal.shape)


@pytest.mark.parametrize("preset", ["default", "strong", "none"])
def test_sensor_kernel_equals_a_numpy_reference_also_into_a_wider_image(preset) -> None:
    # The vectorized kernel gives the bytes of the generator and quantiser its docstring states,
    # also when it writes one half of a side-by-side image (the noise index is the half's own).
    from wristmark.sim.render.sensor import sensor_image

    rng = np.random.default_rng(2)
    st = noise_preset(preset)
    for shape in ((37, 53, 3), (41, 29)):  # odd sizes: spans that start and end inside a generator word
        sig = (rng.random(shape) * 280 - 10).astype(np.float32)
        ref = _reference_sensor(sig, st, 987654321)
        assert np.array_equal(sensor_image(sig, st, 987654321), ref)
        wide = np.full((shape[0], 2 * shape[1], *shape[2:]), 7, np.uint8)
        got = sensor_image(sig, st, 987654321, out=wide[:, shape[1] :])
        assert np.array_equal(got, ref) and np.array_equal(wide[:, shape[1] :], ref)
        assert np.all(wide[:, : shape[1]] == 7)  # the other half untouched


@pytest.mark.parametrize("settings", [noise_preset("default"), noise_preset("strong")])
def test_tile_row_optics_equal_the_whole_frame_exactly(half_camera, settings) -> None:
    # The arm's optics run per tile row over the cached background's: in colour bit for bit the
    # optics of the whole frame (in grey OpenCV's conversion rounds differently by position:
    # within 1e-4, test_incremental_optics_equal_full_frame).
    r = StereoRenderer(half_camera, MarkerModel(), settings, seed=3)
    for shape in (arm_shape(RobotParams(), PSI), arm_shape(RobotParams(), HOME_PSI)):
        for cam in (0, 1):
            assert np.array_equal(r.signal(shape, cam), r.signal(shape, cam, incremental=False))


def test_reused_buffers_leave_no_trace_and_side_by_side_equals_the_pair() -> None:
    # The renderer writes the arm into buffers it keeps and restores: a frame does not depend on
    # the frames before it, and the side-by-side image holds exactly the two images of render().
    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.35)
    a = StereoRenderer(cam, MarkerModel(), noise_preset("default"), seed=9)
    b = StereoRenderer(cam, MarkerModel(), noise_preset("default"), seed=9)
    other, shape = arm_shape(RobotParams(), PSI), arm_shape(RobotParams(), HOME_PSI)
    a.render(other)  # frame 0: another arm
    b.render(shape)
    pa = a.render(shape)  # frame 1 (same noise stream): the same arm
    both, pb = b.render_side_by_side(shape)
    w = cam.image_size[0]
    assert np.array_equal(pa.left, pb.left) and np.array_equal(pa.right, pb.right)
    assert np.array_equal(both[:, :w], pa.left) and np.array_equal(both[:, w:], pa.right)
    assert np.shares_memory(both, pb.left) and pa.left.flags.c_contiguous
    for k in (0, 1):
        assert np.array_equal(a._rad[k], a._bg[k]) and np.array_equal(a._sig[k], a._bg_signal[k])


def test_precomputed_centre_rays_are_the_ray_maps_pixel_centres() -> None:
    # One sample per pixel traces the rays of RayMap.dirs: through each raw pixel's centre, the
    # normalized coordinates of its undistorted position, unit length.
    from wristmark.sim.render.arm import RayMap
    from wristmark.sim.render.raycast import TILE

    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    rm = RayMap(cam.right, cam.image_size)
    ty, tx = rm.tiles
    d = rm.dirs.transpose(0, 3, 1, 2).reshape(ty, TILE, TILE, tx, 3).transpose(0, 1, 3, 2, 4)
    d = d.reshape(ty * TILE, tx * TILE, 3)  # (v, u, xyz)
    xy = rm.xy[1:-1, 1:-1]
    ray = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], axis=2)
    np.testing.assert_allclose(d, ray / np.linalg.norm(ray, axis=2, keepdims=True), rtol=0, atol=1e-15)
    w, h = cam.image_size
    uv = cam.right.project(d[h // 3, w // 2][None, :] * 0.1)[0]
    np.testing.assert_allclose(uv, [w // 2, h // 3], atol=1e-6)


def test_building_and_rendering_leave_opencv_threads_alone() -> None:
    """The renderer changes no process state (it used to set one OpenCV thread when built and
    in every optics call; ``wristmark.warm_up`` is the explicit call that does)."""
    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    before = cv2.getNumThreads()
    cv2.setNumThreads(3)
    try:
        r = StereoRenderer(cam, MarkerModel(), noise_preset("default", motion_blur=2.0), seed=2)
        r.render(arm_shape(RobotParams(), PSI))
        assert cv2.getNumThreads() == 3
    finally:
        cv2.setNumThreads(before)
