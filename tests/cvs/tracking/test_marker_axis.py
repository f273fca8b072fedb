"""Which way the marker points: image evidence (cvs.tracking.axis) and the tracker's order of priors.

The sleeve reprojects identically after a half turn about x_wm, so the tip's side comes from the
image. Our scenes have the arm entering from the left; a camera rolled by pi about its optical
axis sees the same arm with the tip pointing LEFT, where the default prior (+x) is wrong.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.cvs.tracking.axis import AxisEvidenceSettings, axis_evidence
from wristmark.cvs.tracking.stereo_pose import HALF_TURN_X
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer
from wristmark.sim.visibility import random_visible_psi

CAM = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.5)
MARKER = MarkerModel()
SPREAD = (0.25, 0.012, 0.2, 0.6, 0.3, 0.6)  # as `wristmark render`


def _rolled(cam: StereoCamera) -> StereoCamera:
    """The endoscope rolled by pi about its optical axis: the image turns upside down."""
    W = np.asarray(cam.T_world_left, float) @ np.diag([-1.0, -1.0, 1.0, 1.0])
    return dataclasses.replace(cam, T_world_left=W)


def _frames(cam: StereoCamera, n: int, seed: int) -> list[RenderedPair]:
    params = RobotParams()
    rng = np.random.default_rng(seed)
    r = StereoRenderer(cam, MARKER, RenderSettings(), seed=seed)
    return [r.render(arm_shape(params, random_visible_psi(params, cam, MARKER, rng, SPREAD))) for _ in range(n)]


@pytest.fixture(scope="module")
def upright() -> list[RenderedPair]:
    return _frames(CAM, 3, 31)


@pytest.fixture(scope="module")
def rolled() -> list[RenderedPair]:
    return _frames(_rolled(CAM), 3, 32)


def test_rolled_camera_sees_the_tip_pointing_left(rolled: list[RenderedPair]) -> None:
    for f in rolled:
        assert f.T_left_marker[0, 2] < -0.5  # z_wm towards -x of the image: the default prior is wrong


@pytest.mark.parametrize("which", ["upright", "rolled"])
def test_evidence_favours_the_true_direction_and_is_odd(which: str, request: pytest.FixtureRequest) -> None:
    frames: list[RenderedPair] = request.getfixturevalue(which)
    cam = CAM if which == "upright" else _rolled(CAM)
    for f in frames:
        e = axis_evidence((f.left, f.right), cam, MARKER, f.T_left_marker)
        assert e > AxisEvidenceSettings().decide, e
        flipped = axis_evidence((f.left, f.right), cam, MARKER, f.T_left_marker @ HALF_TURN_X)
        assert flipped == pytest.approx(-e, abs=1e-12)


def test_no_arm_no_evidence(upright: list[RenderedPair]) -> None:
    """A flat grey image: nothing on either side of the sleeve, so no decision."""
    f = upright[0]
    grey = np.full_like(f.left, 120)
    assert axis_evidence((grey, grey), CAM, MARKER, f.T_left_marker) == 0.0


def test_tracker_finds_the_tip_pointing_left_from_the_image(rolled: list[RenderedPair]) -> None:
    tracker = MarkerTracker(_rolled(CAM), MARKER)
    for f in rolled:
        tracker.reset()
        res = tracker.track(f.left, f.right)
        assert res.ok and res.axis_source == "image" and res.axis_score > AxisEvidenceSettings().decide
        assert res.tip_left is not None and np.linalg.norm(res.tip_left - f.tip_left) < 0.2e-3


def test_a_callers_hint_comes_first(rolled: list[RenderedPair]) -> None:
    """A (wrong) hint from the caller is obeyed: the same fit, z_wm reversed, tip 30 mm away."""
    tracker = MarkerTracker(_rolled(CAM), MARKER)
    f = rolled[0]
    res = tracker.track(f.left, f.right, axis_hint_left=-f.T_left_marker[:3, 2])
    assert res.ok and res.axis_source == "hint"
    assert res.T_left_marker is not None and res.tip_left is not None
    assert float(res.T_left_marker[:3, 2] @ f.T_left_marker[:3, 2]) < -0.99
    assert np.linalg.norm(res.tip_left - f.tip_left) == pytest.approx(2 * MARKER.tip_offset, abs=0.3e-3)


def test_tracking_keeps_the_direction_from_pair_to_pair(rolled: list[RenderedPair]) -> None:
    """The same pair again is found in the ROI: the previous pose fixes the direction."""
    tracker = MarkerTracker(_rolled(CAM), MARKER)
    f = rolled[1]
    first = tracker.track(f.left, f.right)
    again = tracker.track(f.left, f.right)
    assert first.ok and again.ok and again.axis_source == "previous"
    assert first.tip_left is not None and again.tip_left is not None
    assert np.linalg.norm(again.tip_left - f.tip_left) < 0.2e-3


@pytest.mark.parametrize("which", ["upright", "rolled"])
def test_the_arm_width_evidence_favours_the_true_direction_decisively(which: str,
                                                                      request: pytest.FixtureRequest) -> None:
    """At ``arm_offsets`` alone, bands under ``arm_min_edge`` dropped (MarkerTracker._orient's
    arm-width check): decisive for the true direction on our renders, and odd."""
    frames: list[RenderedPair] = request.getfixturevalue(which)
    cam = CAM if which == "upright" else _rolled(CAM)
    s = AxisEvidenceSettings()
    arm = dataclasses.replace(s, offsets=s.arm_offsets, min_band_edge=s.arm_min_edge)
    for f in frames:
        e = axis_evidence((f.left, f.right), cam, MARKER, f.T_left_marker, arm)
        assert e >= s.decide + s.margin, e
        assert axis_evidence((f.left, f.right), cam, MARKER, f.T_left_marker @ HALF_TURN_X, arm) == pytest.approx(-e)


def test_bands_without_an_edge_above_min_band_edge_count_for_nothing(upright: list[RenderedPair]) -> None:
    f = upright[0]
    s = AxisEvidenceSettings()
    assert axis_evidence((f.left, f.right), CAM, MARKER, f.T_left_marker, dataclasses.replace(s, min_band_edge=0.0)) \
        == axis_evidence((f.left, f.right), CAM, MARKER, f.T_left_marker, s)
    assert axis_evidence((f.left, f.right), CAM, MARKER, f.T_left_marker,
                         dataclasses.replace(s, min_band_edge=255.0 * 24)) == 0.0  # no edge is that strong


@pytest.mark.parametrize("field", ["min_band_edge", "arm_min_edge"])
@pytest.mark.parametrize("value", [-1.0, float("nan")])
def test_edge_floors_must_not_be_negative(field: str, value: float) -> None:
    with pytest.raises(InputError, match=field):
        AxisEvidenceSettings(**{field: value})
