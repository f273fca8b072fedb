"""MarkerTracker._retry_other_view: a view left without a chain is searched where the other
view's chain says its corners are, with a lower CL threshold (TrackerSettings.other_view_cl_scale)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.cvs.tracking.pbr_pairs import load_pbr_pair
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

CODED = MarkerModel.load(CONFIG_DIR / "marker_coded.yaml")


def test_a_corner_row_half_hidden_by_the_stripe_in_one_view_is_tracked_with_its_roll() -> None:
    """Path-traced pair 57 of seed 2323 (tests/data/pbr/coded_stripe_row): the right view's chain
    steps over the corner under the stripe; the left view's corner beside it falls under the CL
    threshold (0.057 against 0.06), so without the search the pair is lost."""
    left, right, truth = load_pbr_pair("coded_stripe_row")
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    res = MarkerTracker(cam, CODED).track(left, right)
    assert res.ok, res.reason
    assert "other_view" in res.timings and res.match is not None and res.match.n_pairs >= 4
    assert np.linalg.norm(res.tip_left - np.asarray(truth["tip_left"])) < 0.05e-3
    assert res.roll_known
    off = MarkerTracker(cam, CODED, TrackerSettings(other_view_cl_scale=0.0)).track(left, right)
    assert not off.ok and "other_view" not in off.timings


@pytest.mark.parametrize("kw", [dict(other_view_cl_scale=1.5), dict(other_view_cl_scale=float("nan")),
                                dict(other_view_depths_m=(0.2, 0.02)), dict(other_view_depths_m=(0.0, 0.1))])
def test_bad_settings_are_refused(kw: dict) -> None:
    with pytest.raises(InputError, match="other_view"):
        TrackerSettings(**kw)
