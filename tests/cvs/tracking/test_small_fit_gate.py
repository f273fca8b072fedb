"""The small-fit gate (TrackerSettings.max_small_fit_tip_sigma_m, MarkerTracker._small_fit_sigma):
one arm's fit whose corners are under gate_min_spacing_px apart is judged with every corner at
corner_sigma_px times its residual, refused above the bound, and reports that sigma
(tests/data/small_marker: the single-tendon arm's loop at 0.25 x)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings, _median_spacing
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.sim.setup import load_setup

DATA = Path(__file__).resolve().parents[2] / "data" / "small_marker"


def small_pair(name: str) -> tuple[Any, Any, Any, np.ndarray, np.ndarray]:
    """(tracking camera at 0.25 x, marker, (left, right), true tip in {w}, the axis hint in {ll})."""
    setup = load_setup(robot=CONFIG_DIR / "robots" / "single_tendon.yaml")
    setup = dataclasses.replace(setup, rig=dataclasses.replace(setup.rig, image_scale=0.25))
    cam = setup.tracking_camera
    truth = json.loads((DATA / name / "truth.json").read_text())
    views = tuple(cv2.imread(str(DATA / name / f"{side}.png")) for side in ("left", "right"))
    W = np.asarray(cam.T_world_left, float)
    return cam, setup.marker, views, np.asarray(truth["tip_world"]), W[:3, :3].T @ np.asarray(truth["axis_hint_world"])


def tip_error_mm(cam: Any, res: Any, truth: np.ndarray) -> float:
    W = np.asarray(cam.T_world_left, float)
    return float(1e3 * np.linalg.norm(W[:3, :3] @ np.asarray(res.tip_left) + W[:3, 3] - truth))


def test_a_wrong_fit_of_a_small_marker_is_refused_by_its_residual() -> None:
    cam, marker, (left, right), truth, hint = small_pair("single_tendon_wrong")
    off = MarkerTracker(cam, marker, TrackerSettings(max_small_fit_tip_sigma_m=math.inf)).track(left, right, hint)
    assert off.ok and _median_spacing(off.corners_left, off.corners_right) < 23  # the contrast gate's floor
    assert tip_error_mm(cam, off, truth) > 10 and math.isnan(off.tip_sigma_m)  # wrong, and nothing said so
    res = MarkerTracker(cam, marker).track(left, right, hint)
    assert not res.ok and res.tip_left is None, res
    got = re.search(r"uncertain by ([0-9.]+) mm at a small marker's corner noise", res.reason)
    assert got and float(got.group(1)) > 1.5, res.reason
    assert res.pose is not None  # the fit is kept for the next frame's search, not reported


def test_a_good_fit_of_a_small_marker_is_kept_and_reports_an_honest_sigma() -> None:
    cam, marker, (left, right), truth, hint = small_pair("single_tendon_good")
    res = MarkerTracker(cam, marker).track(left, right, hint)
    assert res.ok and _median_spacing(res.corners_left, res.corners_right) < 23, res.reason
    err = tip_error_mm(cam, res, truth)
    assert 0.2e-3 < res.tip_sigma_m < 1.5e-3 and err < 3e3 * res.tip_sigma_m, (err, res.tip_sigma_m)
    off = MarkerTracker(cam, marker, TrackerSettings(max_small_fit_tip_sigma_m=math.inf)).track(left, right, hint)
    assert off.ok and np.allclose(off.tip_left, res.tip_left) and math.isnan(off.tip_sigma_m)  # the same fit


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan")])
def test_the_small_fit_bound_is_validated(bad: float) -> None:
    with pytest.raises(InputError, match="max_small_fit_tip_sigma_m"):
        TrackerSettings(max_small_fit_tip_sigma_m=bad)
