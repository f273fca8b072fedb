"""Several arms in one stereo pair: each arm alone where they are apart, mutual occlusion where
they cross (pixels and the corners' ``occluded`` truth), order of the arms, input checks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.marker.code import CODE_WORDS, coded_marker
from wristmark.models.arm_shape import ArmShape, arm_shape, transformed
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import RenderSettings, noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer

PSI = np.array(HOME_PSI) + [0.2, 0.0, 0.1, 0.3, 0.0, 0.2]
RAW = RenderSettings(read_noise=0.0, shot_gain=0.0, blur_sigma=0.0, vignetting=0.0)  # signal = radiance
# two coded sleeves (their patches concatenated, each sleeve drawing only its own)
MARKERS = (coded_marker(words=tuple(reversed(CODE_WORDS))), coded_marker())


def _shift(d) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = d
    return T


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _moved_in_left(cam, shape: ArmShape, T_ll: np.ndarray) -> ArmShape:
    """The shape moved by T_ll, a rigid motion written in the left camera frame {ll}."""
    W = np.asarray(cam.T_world_left, float)
    return transformed(shape, W @ T_ll @ np.linalg.inv(W))


@pytest.fixture(scope="module")
def cam():
    return scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.5)


@pytest.fixture(scope="module")
def apart(cam) -> tuple[ArmShape, ArmShape]:
    """Two arms ~30 mm apart across the image (up / down in {ll}), both seen whole."""
    a = arm_shape(RobotParams(), PSI)
    return _moved_in_left(cam, a, _shift([0, -0.014, 0])), _moved_in_left(cam, a, _shift([0, 0.016, 0]))


@pytest.fixture(scope="module")
def crossing(cam) -> tuple[ArmShape, ArmShape]:
    """Arm B: arm A turned 30 deg about the optical axis through A's marker, 12 mm nearer the
    camera, its sleeve over the lower half of A's."""
    a = arm_shape(RobotParams(), PSI)
    W = np.asarray(cam.T_world_left, float)
    p = (np.linalg.inv(W) @ a.T_world_marker)[:3, 3]  # A's marker origin in {ll}
    turn = _shift(p) @ _rot_z(30.0) @ _shift(-p)
    z_b = (turn @ np.linalg.inv(W) @ a.T_world_marker)[:3, 2]
    return a, _moved_in_left(cam, a, _shift([0, 0.004, -0.012]) @ _shift(0.004 * z_b) @ turn)


def test_transformed_moves_every_frame_rigidly() -> None:
    a = arm_shape(RobotParams(), PSI)
    T = _shift([0.01, -0.02, 0.003]) @ _rot_z(40.0)
    b = transformed(a, T)
    np.testing.assert_allclose(b.centreline, a.centreline @ T[:3, :3].T + T[:3, 3], atol=1e-15)
    np.testing.assert_allclose(b.T_world_marker, T @ a.T_world_marker, atol=1e-15)
    np.testing.assert_allclose(b.tip, T[:3, :3] @ a.tip + T[:3, 3], atol=1e-15)
    np.testing.assert_allclose(b.frames.T_world_1b, T @ a.frames.T_world_1b, atol=1e-15)
    assert b.radius == a.radius and b.distal_start == a.distal_start
    with pytest.raises(InputError, match="rigid"):
        transformed(a, np.diag([2.0, 1.0, 1.0, 1.0]))


def test_arms_apart_each_as_if_alone(cam, apart) -> None:
    # Far apart, each arm's pixels of the two-arm signal (noise free, with the optics) are those
    # of the arm rendered alone, bit for bit, away from the other arm; the tile-row optics of
    # the union of the arms' rows equal the whole frame's.
    st = noise_preset("default")
    both = StereoRenderer(cam, MARKERS, st, seed=3)
    alone = [StereoRenderer(cam, m, st, seed=3) for m in MARKERS]
    k = np.ones((17, 17), np.uint8)
    for c in (0, 1):
        two = both.signal(apart, c)
        np.testing.assert_array_equal(two, both.signal(apart, c, incremental=False))
        one = [r.signal(s, c) for r, s in zip(alone, apart)]
        bg = both._bg_signal[c]
        drawn = [np.any(o != bg, axis=2) for o in one]
        near = [cv2.dilate(d.astype(np.uint8), k).astype(bool) for d in drawn]
        assert drawn[0].sum() > 5000 and drawn[1].sum() > 5000
        assert not np.any(near[0] & near[1])  # really apart
        for i in (0, 1):
            away = ~near[1 - i]
            np.testing.assert_array_equal(two[away], one[i][away])
        assert np.array_equal(two[~near[0] & ~near[1]], bg[~near[0] & ~near[1]])


def test_crossing_arms_hide_the_farther_sleeve(cam, crossing) -> None:
    # B passes in front of A's sleeve: the corners of A under B are flagged occluded in each
    # camera and their pixels are B's (as B alone draws them), not A's; A's other facing
    # corners show A; nothing of A hides B.
    both = StereoRenderer(cam, MARKERS, RAW, seed=1)
    a_alone, b_alone = (StereoRenderer(cam, m, RAW, seed=1) for m in MARKERS)
    scene = both.render_arms(crossing)
    checked = {True: 0, False: 0}
    for c in (0, 1):
        two = both.signal(crossing, c)
        a1, b1 = a_alone.signal(crossing[0], c), b_alone.signal(crossing[1], c)
        b_drawn = cv2.dilate(np.any(b1 != both._bg_signal[c], axis=2).astype(np.uint8), np.ones((5, 5), np.uint8))
        truth = (scene.arms[0].corners_left, scene.arms[0].corners_right)[c]
        assert not any(t.occluded for t in (scene.arms[1].corners_left, scene.arms[1].corners_right)[c])
        diff_a = []
        for t in truth:
            if t.cos_view < 0.2:
                continue
            u, v = int(round(t.uv[0])), int(round(t.uv[1]))
            if t.occluded:
                np.testing.assert_allclose(two[v, u], b1[v, u], atol=1.0)
                diff_a.append(np.abs(two[v, u] - a1[v, u]).max())
            else:
                assert not b_drawn[v, u]  # not under B's silhouette
                np.testing.assert_allclose(two[v, u], a1[v, u], atol=1.0)
            checked[t.occluded] += 1
        assert max(diff_a) > 30  # the occluded corners really show B
    assert checked[True] >= 4 and checked[False] >= 4


def test_order_of_the_arms_swaps_the_truth_not_the_image(cam, crossing) -> None:
    st = noise_preset("default")
    ab = StereoRenderer(cam, MARKERS, st, seed=6).render_arms(crossing)
    ba = StereoRenderer(cam, MARKERS[::-1], st, seed=6).render_arms(crossing[::-1])
    assert np.array_equal(ab.left, ba.left) and np.array_equal(ab.right, ba.right)
    for x, y in ((ab.arms[0], ba.arms[1]), (ab.arms[1], ba.arms[0])):
        np.testing.assert_array_equal(x.T_left_marker, y.T_left_marker)
        np.testing.assert_array_equal(x.tip_left, y.tip_left)
        assert x.corners_left == y.corners_left and x.corners_right == y.corners_right
    assert any(t.occluded for t in ab.arms[0].corners_left)
    assert not np.allclose(ab.arms[0].T_left_marker, ab.arms[1].T_left_marker)


def test_scene_truth_and_side_by_side(cam, apart) -> None:
    # Per arm the truth of a one-arm render (no corner occluded when apart); the side-by-side
    # variant holds the same two images.
    st = noise_preset("default")
    scene = StereoRenderer(cam, MARKERS, st, seed=4).render_arms(apart)
    both, sbs = StereoRenderer(cam, MARKERS, st, seed=4).render_arms_side_by_side(apart)
    w = cam.image_size[0]
    assert np.array_equal(both[:, :w], scene.left) and np.array_equal(both[:, w:], scene.right)
    assert np.shares_memory(both, sbs.left)
    for arm, shape, m in zip(scene.arms, apart, MARKERS):
        one = StereoRenderer(cam, m, st, seed=4).render(shape)
        np.testing.assert_array_equal(arm.T_left_marker, one.T_left_marker)
        np.testing.assert_array_equal(arm.tip_left, one.tip_left)
        assert arm.corners_left == one.corners_left and arm.corners_right == one.corners_right
        assert not any(t.occluded for t in one.corners_left + one.corners_right)


def test_shapes_must_match_the_markers(cam, apart) -> None:
    r = StereoRenderer(cam, MARKERS, RenderSettings(), seed=0)
    with pytest.raises(InputError, match="1 arm shape"):
        r.render_arms(apart[:1])
    with pytest.raises(InputError, match="one shape per marker"):
        r.render(apart[0])
    with pytest.raises(InputError, match="3 arm shape"):
        r.signal([*apart, apart[0]])
    with pytest.raises(InputError, match="2 arm shape"):
        StereoRenderer(cam, MarkerModel(), RenderSettings(), seed=0).render_arms(apart)
    with pytest.raises(InputError, match="at least one marker"):
        StereoRenderer(cam, (), RenderSettings(), seed=0)
