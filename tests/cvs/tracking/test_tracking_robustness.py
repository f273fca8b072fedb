"""The tracker on hard rendered pairs: motion blur + JPEG, a partly occluded marker, specular
glints on it, the marker cut by the image border, the marker near the border where distortion
is strongest. Each pair is either tracked to the truth or reported as ``ok: false`` with a
reason: never a wrong pose."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackResult
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import tip_position
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import RenderSettings, noise_preset
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer

pytestmark = [pytest.mark.slow]

CAM = load_calibration(CONFIG_DIR / "camera.yaml")
MARKER = MarkerModel()
PARAMS = RobotParams()
HOME = np.asarray(HOME_PSI, float)
WRONG_POSE_MM = 0.5  # an accepted estimate farther than this from the truth is a wrong pose


def _render(settings: RenderSettings, psi: np.ndarray, seed: int = 5) -> RenderedPair:
    return StereoRenderer(CAM, MARKER, settings, seed=seed).render(arm_shape(PARAMS, psi))


def _never_wrong(res: TrackResult, f: RenderedPair) -> float:
    """Tip error [mm] when tracked; inf with a reason when not; fails on a wrong pose."""
    if not res.ok:
        assert res.reason and res.tip_left is None
        return float("inf")
    err = 1000 * float(np.linalg.norm(res.tip_left - f.tip_left))  # type: ignore[operator]
    assert err < WRONG_POSE_MM, f"wrong pose accepted: tip off by {err:.2f} mm"
    return err


@pytest.fixture(scope="module")
def home_frame() -> RenderedPair:
    return _render(noise_preset("default"), HOME)


def _marker_box(f: RenderedPair, left: bool = True) -> tuple[np.ndarray, np.ndarray]:
    uv = np.array([c.uv for c in (f.corners_left if left else f.corners_right)])
    return uv.min(axis=0), uv.max(axis=0)


def test_motion_blur_and_jpeg_are_tracked() -> None:
    f = _render(noise_preset("default", motion_blur=5.0, jpeg_quality=70), HOME)
    err = _never_wrong(MarkerTracker(CAM, MARKER).track(f.left, f.right), f)
    assert err < 0.3


def test_partly_occluded_marker(home_frame: RenderedPair) -> None:
    f = home_frame
    left = f.left.copy()
    lo, hi = _marker_box(f)
    mid = int((lo[1] + hi[1]) / 2)  # a dark instrument over the lower half of the marker
    cv2.rectangle(left, (int(lo[0]) - 40, mid), (int(hi[0]) + 40, int(hi[1]) + 40), (25, 20, 20), -1)
    res = MarkerTracker(CAM, MARKER).track(left, f.right)
    _never_wrong(res, f)


def _glints(f: RenderedPair, n: int, seed: int) -> list[np.ndarray]:
    """Both images with ``n`` saturated highlights (7x3 px ellipses) on the marker each."""
    imgs = []
    rng = np.random.default_rng(seed)
    for img, is_left in ((f.left, True), (f.right, False)):
        img = img.copy()
        lo, hi = _marker_box(f, is_left)
        for _ in range(n):
            c = rng.uniform(lo, hi).astype(int)
            cv2.ellipse(img, (int(c[0]), int(c[1])), (7, 3), float(rng.uniform(0, 180)), 0, 360, (255, 255, 255), -1)
        imgs.append(cv2.GaussianBlur(img, (0, 0), 0.8))
    return imgs


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_specular_glint_on_the_marker_is_tolerated(home_frame: RenderedPair, seed: int) -> None:
    err = _never_wrong(MarkerTracker(CAM, MARKER).track(*_glints(home_frame, 1, seed)), home_frame)
    assert err < 0.3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_many_glints_never_give_a_wrong_pose(home_frame: RenderedPair, seed: int) -> None:
    _never_wrong(MarkerTracker(CAM, MARKER).track(*_glints(home_frame, 4, seed)), home_frame)


def test_marker_cut_by_the_image_border(home_frame: RenderedPair) -> None:
    f = home_frame
    imgs = []
    for img, is_left in ((f.left, True), (f.right, False)):
        img = img.copy()
        lo, hi = _marker_box(f, is_left)
        cut = int(lo[0] + 0.4 * (hi[0] - lo[0]))  # everything left of here is outside the sensor
        img[:, :cut] = 0
        imgs.append(img)
    _never_wrong(MarkerTracker(CAM, MARKER).track(*imgs), f)


def test_marker_near_the_border_under_strong_distortion() -> None:
    centre = tip_position(PARAMS, HOME)
    target = centre + np.array([0.020, -0.010, 0.020])  # the cube corner nearest the top of the image
    psi = solve_tip_ik(PARAMS, target, HOME).psi
    f = _render(noise_preset("default"), psi)
    lo, _ = _marker_box(f)
    assert lo[1] < 120  # the marker really is near the border
    res = MarkerTracker(CAM, MARKER).track(f.left, f.right)
    err = _never_wrong(res, f)
    assert err < 0.3  # and it is still tracked there
