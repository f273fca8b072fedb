"""cvs.tracking.foreshortening and the tracker's use of it (TrackerSettings.foreshortening_*):
the HTM fit's bias at a corner the camera sees obliquely, drawn at a pose, and removed from the
tracked corners of real rendered pixels."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest

from wristmark.cli.render import psi_spread
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.tracking.foreshortening import corner_patch, htm_bias
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.sleeve_facing import corner_facing
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.arm_shape import arm_shape
from wristmark.models.arm_spec import load_loop_arm
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.visibility import random_visible_psi


@pytest.fixture(scope="module")
def camera() -> StereoCamera:
    return load_calibration(default_config("camera.yaml"))


def _side_on(marker: MarkerModel, first_deg: float, depth: float = 0.06) -> np.ndarray:
    """{wm} in the camera frame: the sleeve's axis across the view (z_wm along +x_cam), ``depth``
    [m] ahead, rolled so that corner k's normal turns k beta - ``first_deg`` from the line of
    sight back to the lens (corners 0, 11 and 10 at ``first_deg`` + 0, 30 and 60 deg)."""
    a = np.radians(first_deg)
    Rz = np.array([[np.cos(a), np.sin(a), 0.0], [-np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    base = np.column_stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # x_wm -> -z_cam, z_wm -> +x_cam
    T = np.eye(4)
    T[:3, :3] = base @ Rz
    T[:3, 3] = [0.0, 0.0, depth]
    return T


def _toward_silhouette(camera: StereoCamera, T: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The image direction (N, 2) of each corner's circumference, pointing where it faces the lens less."""
    a = np.arctan2(P[:, 1], P[:, 0])
    around = np.column_stack([-np.sin(a), np.cos(a), np.zeros_like(a)])
    f0 = corner_facing(T, P, np.zeros(3))
    f1 = corner_facing(T, P + 1e-5 * around, np.zeros(3))
    step = np.where((f1 < f0)[:, None], around, -around) * 1e-5
    X = P @ T[:3, :3].T + T[:3, 3]
    d = camera.left.project(X + step @ T[:3, :3].T) - camera.left.project(X)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_a_corner_facing_the_camera_is_fitted_where_it_projects(camera: StereoCamera) -> None:
    """The drawing's geometry (the calibrated distortion, the cylinder, the checker's columns) puts
    a corner seen square-on where the camera projects it: the fit lands within 0.02 px."""
    marker = MarkerModel()
    T = _side_on(marker, 0.0)
    P = marker.corners()
    facing = corner_facing(T, P, np.zeros(3))
    assert facing[0] > 0.99
    bias = htm_bias(camera.left, T, P[:1], np.array([30.0]), marker.radius, marker.beta, facing[:1], 1.0, 1.0)
    assert np.linalg.norm(bias[0]) < 0.02


def test_the_fit_lands_away_from_the_silhouette_more_as_the_sleeve_turns_and_more_with_blur(
        camera: StereoCamera) -> None:
    """Corners whose normals turn 10, 40 and 70 deg from the lens (cosines 0.98, 0.73, 0.27):
    where the sleeve turns away, the fit lands on the wider, brighter side (towards the lens),
    more as it turns and more with more blur; square-on, hardly at all."""
    marker = MarkerModel()
    T = _side_on(marker, 10.0)
    P = marker.corners()[[0, 11, 10]]  # 30-60 px apart in the image
    facing = corner_facing(T, P, np.zeros(3))
    assert facing[0] > 0.95 and 0.7 < facing[1] < 0.8 and 0.25 < facing[2] < 0.4
    toward = _toward_silhouette(camera, T, P)
    along = {}
    for blur in (0.5, 1.5):
        bias = htm_bias(camera.left, T, P, np.full(3, 30.0), marker.radius, marker.beta, facing, 1.0, blur)
        along[blur] = np.einsum("ij,ij->i", bias, toward)
    assert along[1.5][2] < along[1.5][1] < 0.0 and abs(along[1.5][0]) < 0.03
    assert along[1.5][2] < -0.1  # a tenth of a pixel and more at a cosine of 0.27
    assert along[1.5][2] < along[0.5][2] < 0.0
    # above max_facing nothing is drawn
    assert not htm_bias(camera.left, T, P, np.full(3, 30.0), marker.radius, marker.beta, facing, 0.2, 1.5).any()


def test_off_the_sleeve_is_dark_and_a_square_is_shaded_by_its_cosine(camera: StereoCamera) -> None:
    marker = MarkerModel()
    T = _side_on(marker, 0.0)
    X = marker.corners()[:1] @ T[:3, :3].T + T[:3, 3]
    centre = camera.left.project(X)[0]
    patch, _ = corner_patch(camera.left, T, marker.radius, marker.beta, centre, 7, 3, 0.0)
    assert patch.shape == (15, 15) and patch.dtype == np.float32
    assert patch.max() > 190 and patch.min() < 15  # a facing white square, a dark one
    # the silhouette: a window centred on the sleeve's edge, seen side-on (the normal 90 deg from the lens)
    T_edge = _side_on(marker, 90.0)
    X = marker.corners()[:1] @ T_edge[:3, :3].T + T_edge[:3, 3]
    edge = corner_patch(camera.left, T_edge, marker.radius, marker.beta, camera.left.project(X)[0], 7, 3, 0.0)[0]
    assert (edge == 0).sum() > 50 and edge.max() < 150  # beyond it nothing; before it, seen obliquely


def _random_view(rng: np.random.Generator) -> np.ndarray:
    """{wm} in the camera frame: the sleeve side-on, rolled, tilted and shifted at random, 40-100 mm away."""
    T = _side_on(MarkerModel(), float(rng.uniform(0.0, 360.0)), float(rng.uniform(0.04, 0.1)))
    t = np.radians(rng.uniform(-30.0, 30.0))
    T[:3, :3] = np.array([[np.cos(t), 0.0, np.sin(t)], [0.0, 1.0, 0.0], [-np.sin(t), 0.0, np.cos(t)]]) @ T[:3, :3]
    T[:2, 3] = rng.uniform(-0.01, 0.01, 2)
    return T


def test_the_adaptive_drawing_gives_the_bias_of_the_full_one(camera: StereoCamera) -> None:
    """Drawing only the pixels an edge, the corner or the silhouette crosses (or whose shading
    bends) with all sub-samples moves the drawn bias by a few thousandths of a pixel at most, at
    every facing up to 0.7 and blur of 0-1.5 px (stop 62: 0.003 px at most over 631 corners,
    median 1e-6), where the shortcut's first version, which compared dark and white instead of
    which square, moved it by up to 1.5 px beside the silhouette."""
    marker = MarkerModel()
    P = marker.corners()
    rng = np.random.default_rng(0)
    moved = []
    for _ in range(60):
        T = _random_view(rng)
        facing = corner_facing(T, P, np.zeros(3))
        spacing = rng.uniform(15.0, 60.0, P.shape[0])
        blur = float(rng.choice([0.0, 0.8, 1.0, 1.5]))
        full = htm_bias(camera.left, T, P, spacing, marker.radius, marker.beta, facing, 0.7, blur, adaptive=False)
        fast = htm_bias(camera.left, T, P, spacing, marker.radius, marker.beta, facing, 0.7, blur)
        drawn = (facing > 0) & (facing <= 0.7)
        assert not fast[~drawn].any()
        moved.extend(np.linalg.norm(fast - full, axis=1)[drawn])
    assert len(moved) > 150
    assert max(moved) < 0.01 and np.median(moved) < 1e-4


@pytest.mark.wallclock
def test_the_adaptive_drawing_costs_far_less_than_the_full_one(camera: StereoCamera) -> None:
    """The drawing is most of the correction's price in ROI tracking (docs/notes/tracking-time-budget.md):
    the adaptive one takes at most 0.6 of the full one's time (stop 62: ~0.3), medians of 15 x 20 patches."""
    marker = MarkerModel()
    rng = np.random.default_rng(1)
    views = [_random_view(rng) for _ in range(20)]
    centres = [camera.left.project(marker.corners()[:1] @ T[:3, :3].T + T[:3, 3])[0] for T in views]

    def draw(adaptive: bool) -> float:
        t0 = time.perf_counter()
        for T, c in zip(views, centres):
            corner_patch(camera.left, T, marker.radius, marker.beta, c, 7, adaptive=adaptive)
        return time.perf_counter() - t0

    draw(True), draw(False)
    full, fast = [], []
    for _ in range(15):
        full.append(draw(False))
        fast.append(draw(True))
    assert np.median(fast) < 0.6 * np.median(full)


def test_bad_settings_are_refused() -> None:
    for bad in ({"foreshortening_max_facing": 1.5}, {"foreshortening_max_facing": float("nan")},
                {"foreshortening_blur_px": -1.0}, {"foreshortening_blur_px": float("inf")},
                {"foreshortening_min_spacing_px": -1.0}, {"foreshortening_min_spacing_px": float("nan")}):
        with pytest.raises(InputError, match="foreshortening"):
            TrackerSettings(**bad)


@pytest.fixture(scope="module")
def rendered() -> list:
    """Eight fast-renderer pairs of the reference sleeve at random visible poses (default sensor,
    0.8 px of optics blur)."""
    cam = load_calibration(default_config("camera.yaml"))
    marker = MarkerModel()
    params = load_loop_arm(None, marker)
    rng = np.random.default_rng(7)
    renderer = StereoRenderer(cam, marker, noise_preset("default"), seed=7)
    return [renderer.render(arm_shape(params, random_visible_psi(params, cam, marker, rng, psi_spread(params), 400)))
            for _ in range(8)]


def test_the_tracked_corners_lose_their_bias_where_the_sleeve_turns_away(rendered: list) -> None:
    """On real rendered pixels: the used corners facing the camera at a cosine of 0.7 or less lie
    nearer their true projections with the bias drawn at the fit and removed (RMS over both views'
    corners of eight pairs), and no tip moves far."""
    cam = load_calibration(default_config("camera.yaml"))
    marker = MarkerModel()
    on = MarkerTracker(cam, marker)
    off = MarkerTracker(cam, marker, replace(TrackerSettings(), foreshortening_max_facing=0.0))
    assert on.settings.foreshortening_max_facing == 0.7  # on by default
    errors: dict[str, list[float]] = {"on": [], "off": []}
    tips: dict[str, list[float]] = {"on": [], "off": []}
    T_right = np.eye(4)
    T_right[:3, :3], T_right[:3, 3] = cam.R, np.asarray(cam.T, float).reshape(3)
    for pair in rendered:
        for name, tracker in (("on", on), ("off", off)):
            tracker.reset()
            res = tracker.track(pair.left, pair.right)
            assert res.ok and res.match is not None and res.tip_left is not None
            assert ("foreshortening" in res.timings) == (name == "on")
            tips[name].append(float(np.linalg.norm(res.tip_left - pair.tip_left)))
            for camera, T, uv, index in ((cam.left, pair.T_left_marker, res.corners_left, res.match.index_left),
                                         (cam.right, T_right @ pair.T_left_marker, res.corners_right,
                                          res.match.index_right)):
                P = marker.corners()
                truth = camera.project(P @ T[:3, :3].T + T[:3, 3])
                facing = corner_facing(T, P, np.zeros(3))
                for u in uv[index >= 0]:
                    k = int(np.argmin(np.linalg.norm(truth - u, axis=1)))
                    if facing[k] <= 0.7:
                        errors[name].append(float(np.linalg.norm(u - truth[k])))
    assert len(errors["off"]) >= 20 and len(errors["on"]) == len(errors["off"])
    before, after = (float(np.sqrt(np.mean(np.square(errors[k])))) for k in ("off", "on"))
    assert after < 0.9 * before, (before, after)
    assert max(abs(a - b) for a, b in zip(tips["on"], tips["off"])) < 0.1e-3
    assert max(tips["on"]) < 0.3e-3


def test_no_correction_where_the_corners_lie_closer_than_the_bound(rendered: list) -> None:
    """Below ``foreshortening_min_spacing_px`` (the chains' median spacing) nothing is drawn: the
    result is the uncorrected one, to the bit."""
    cam = load_calibration(default_config("camera.yaml"))
    marker = MarkerModel()
    far = MarkerTracker(cam, marker, replace(TrackerSettings(), foreshortening_min_spacing_px=1e3))
    off = MarkerTracker(cam, marker, replace(TrackerSettings(), foreshortening_max_facing=0.0))
    on = MarkerTracker(cam, marker)
    moved = 0
    for pair in rendered[:4]:
        got = []
        for tracker in (far, off, on):
            tracker.reset()
            got.append(tracker.track(pair.left, pair.right))
        assert "foreshortening" not in got[0].timings
        np.testing.assert_array_equal(got[0].tip_left, got[1].tip_left)
        moved += int(not np.array_equal(got[2].tip_left, got[1].tip_left))
    assert moved >= 1  # with the default bound it does correct these pairs
