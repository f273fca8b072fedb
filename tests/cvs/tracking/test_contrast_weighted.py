"""The tracker's contrast-weighted solve (TrackerSettings.solve_contrast_noise) on the committed
path-traced pairs (tests/data/pbr): the same direction, roll and corners as the unweighted fit,
the tip a fraction of the corners' noise apart, on each pair."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.sim.dataset import load_dataset

DATA = Path(__file__).resolve().parents[2] / "data" / "pbr"


@pytest.mark.parametrize("name", ["reference_glossy", "coded_glossy", "reference_matte", "coded_matte"])
def test_the_weighted_fit_keeps_the_unweighted_decisions(name: str) -> None:
    ds = load_dataset(DATA / name)
    # the weighting alone: the corners' foreshortening correction (drawn at each fit) is off in both
    weighted = MarkerTracker(ds.camera, ds.marker, replace(TrackerSettings(), foreshortening_max_facing=0.0))
    plain = MarkerTracker(ds.camera, ds.marker, replace(weighted.settings, solve_contrast_noise=0.0))
    assert weighted.settings.solve_contrast_noise > 0
    moved = []
    for (lp, rp), truth in zip(ds.pairs, ds.truth):
        left, right = (cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in (lp, rp))
        weighted.reset()
        plain.reset()
        a, b = plain.track(left, right), weighted.track(left, right)
        assert a.ok and b.ok, (lp.name, a.reason, b.reason)
        assert "weighted" in b.timings and "weighted" not in a.timings
        assert (a.axis_source, a.roll_known) == (b.axis_source, b.roll_known)
        np.testing.assert_array_equal(a.corners_left, b.corners_left)
        assert a.T_left_marker is not None and b.T_left_marker is not None
        assert a.tip_left is not None and b.tip_left is not None
        # the same direction of z_wm and roll: the rotations differ by the fits' small change only
        dR = a.T_left_marker[:3, :3].T @ b.T_left_marker[:3, :3]
        assert np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))) < 1.0
        moved.append(np.linalg.norm(a.tip_left - b.tip_left))
        assert np.linalg.norm(b.tip_left - truth.tip) < 0.25e-3  # half size: 960 x 540
    assert max(moved) < 0.1e-3 and max(moved) > 0.0  # it does something, and little
