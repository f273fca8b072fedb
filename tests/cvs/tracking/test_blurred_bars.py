"""Bar edges measured by a blurred-step fit where the largest gradient's tests refuse them
(print_edges.measure_edges ``blur_fit_px``; TrackerSettings.edge_blur_fit_px and
edge_blur_max_sigma_px): synthetic blurred and clipped edges, a sharp step into a shading ramp,
and the path-traced pair tests/data/pbr/coded_blurred_bars (1515/15)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from tests.cvs.tracking.pbr_pairs import load_pbr_pair
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.print_edges import _profile_peaks
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

EDGE_X = 20.3  # [px] where the synthetic step is, its crop's x


def _step(sigma: float, dark: float, white: float) -> np.ndarray:
    """A 40 x 40 crop with a vertical dark-to-white step at x = EDGE_X blurred by ``sigma`` [px],
    clipped at 255."""
    x = np.arange(40, dtype=float)
    row = dark + (white - dark) * 0.5 * (1.0 + erf((x - EDGE_X) / (math.sqrt(2.0) * sigma)))
    return np.asarray(np.tile(np.minimum(row, 255.0), (40, 1)), np.float32)


def _measure(grey: np.ndarray, blur_px: float, max_sigma: float = 6.0) -> tuple[float, bool]:
    """The one sample at (20, 20) along +x: (offset [px], kept), the fit's sigma up to ``max_sigma``
    [px] (6: its own bound)."""
    off, good = _profile_peaks(grey, 0.0, 0.0, np.array([[20.0, 20.0]]), np.array([[1.0, 0.0]]), 3.5, 12.0,
                               250.0, blur_px, 0.06, max_sigma)
    return float(off[0]), bool(good[0])


def test_a_sharp_edge_is_the_gradients_and_the_fit_is_not_asked() -> None:
    grey = _step(0.7, 40.0, 200.0)
    assert _measure(grey, 0.0) == _measure(grey, 7.5)
    off, kept = _measure(grey, 0.0)
    assert kept and abs(off - (EDGE_X - 20.0)) < 0.15


def test_a_blurred_edge_refused_by_the_gradient_is_found_by_the_fit() -> None:
    grey = _step(2.8, 40.0, 200.0)  # rises by ~0.14 of its span per px: under the gradient's quarter
    assert not _measure(grey, 0.0)[1]
    off, kept = _measure(grey, 7.5)
    assert kept and abs(off - (EDGE_X - 20.0)) < 0.05, off


def test_an_edge_whose_white_half_is_clipped_is_not_fitted() -> None:
    """Its height, blur and place trade off on the dark half alone (fitted here 0.84 px off
    before the white level's test): refused, not guessed."""
    grey = _step(2.0, 60.0, 420.0)  # the white side clips from ~0.2 px past the edge on
    assert not _measure(grey, 0.0)[1] and not _measure(grey, 7.5)[1]
    grey = _step(2.8, 60.0, 240.0)  # the same blurred step whose white is seen: found
    off, kept = _measure(grey, 7.5)
    assert kept and abs(off - (EDGE_X - 20.0)) < 0.05, off


# path-traced 1010/41, a bar edge of the left view at its true place (t = 0): grey levels at
# t = -7.5, -7.0, ..., 7.5 px along its image normal (in-process, stop 58)
RAMP_PROFILE = (8, 7, 6, 6, 7, 7, 8, 9, 10, 11, 14, 20, 28, 39, 51, 65, 80, 97, 113, 127, 139, 150, 161, 173,
                180, 191, 204, 216, 220, 216, 215)


def test_a_step_into_a_shading_ramp_is_not_taken_for_a_wide_blur() -> None:
    """The print's edge rises to mid-grey within ~2 px, then the white square brightens over
    ~5 px more towards the highlight: one blurred step fitted to both widens to sigma ~2.8 px and
    puts the edge ~1.7 px into the ramp. The tracker's fit keeps sigma <= 2.5 px
    (TrackerSettings.edge_blur_max_sigma_px): refused, while a real 2 px blur is still found."""
    x = np.arange(40, dtype=float)
    row = np.interp(x - EDGE_X, np.arange(-7.5, 7.51, 0.5), np.asarray(RAMP_PROFILE, float))
    grey = np.asarray(np.tile(row, (40, 1)), np.float32)
    assert not _measure(grey, 0.0)[1]  # too slow a rise for the gradient
    off, kept = _measure(grey, 7.5)  # no bound on the blur: kept, far into the ramp
    assert kept and off - (EDGE_X - 20.0) > 1.5, off
    assert not _measure(grey, 7.5, 2.5)[1]
    blurred = _step(2.0, 40.0, 200.0)
    assert not _measure(blurred, 0.0)[1]
    off, kept = _measure(blurred, 7.5, 2.5)
    assert kept and abs(off - (EDGE_X - 20.0)) < 0.05, off


def test_a_flat_profile_is_no_edge() -> None:
    grey = np.full((40, 40), 90.0, np.float32) + np.random.default_rng(1).normal(0.0, 2.0, (40, 40)).astype(np.float32)
    assert not _measure(grey, 7.5)[1]


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray, dict]:
    return load_pbr_pair("coded_blurred_bars")


def test_the_close_blurred_coded_sleeve_is_tracked_with_its_roll(pair) -> None:
    left, right, truth = pair
    camera = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    r = MarkerTracker(camera, marker).track(left, right)
    assert r.ok and r.roll_known and r.T_left_marker is not None and r.tip_left is not None, r.reason
    assert "bars_gate" in r.timings  # refused on its three corners a view, kept with the bars
    assert 1e3 * np.linalg.norm(r.tip_left - np.asarray(truth["tip_left"])) < 0.15
    R_true = np.asarray(truth["T_left_marker"])[:3, :3]
    angle = math.degrees(math.acos(np.clip((np.trace(R_true.T @ r.T_left_marker[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)))
    assert angle < 1.0
    off = MarkerTracker(camera, marker, TrackerSettings(edge_blur_fit_px=0.0, reduced_sigma_px=0.0)).track(left, right)
    assert not off.ok and "the tip is uncertain" in off.reason  # the gradient's bars alone do not fix it
    # ... and the reduced search's fit at its measured corner noise is the last resort: 0.30 mm
    # off at 0.70 mm of sigma (with the blurred-step bars, 0.03 mm)
    last = MarkerTracker(camera, marker, TrackerSettings(edge_blur_fit_px=0.0)).track(left, right)
    assert last.ok and last.tip_left is not None and "reduced_refit" in last.timings, last.reason
    error = float(np.linalg.norm(last.tip_left - np.asarray(truth["tip_left"])))
    assert error < 0.4e-3 and error < last.tip_sigma_m


@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf")])
def test_a_bad_blur_fit_width_is_refused(value: float) -> None:
    with pytest.raises(InputError, match="edge_blur_fit_px"):
        TrackerSettings(edge_blur_fit_px=value)


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_largest_blur_is_refused(value: float) -> None:
    with pytest.raises(InputError, match="edge_blur_max_sigma_px"):
        TrackerSettings(edge_blur_max_sigma_px=value)
