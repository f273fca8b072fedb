"""The tracker on the committed path-traced pairs (tests/data/pbr, Mitsuba 3; no Mitsuba needed
here): glossy and matte sleeves under the light beside the lenses, with defocus and JPEG."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.sim.dataset import load_dataset

DATA = Path(__file__).resolve().parents[2] / "data" / "pbr"
SETS = ("reference_glossy", "coded_glossy", "reference_matte", "coded_matte")


def _rotation_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_true.T @ R_est) - 1.0) / 2.0, -1.0, 1.0))))


@pytest.mark.parametrize("name", SETS)
def test_every_path_traced_pair_is_tracked_and_right(name: str) -> None:
    ds = load_dataset(DATA / name)
    coded = ds.marker.code is not None
    tracker = MarkerTracker(ds.camera, ds.marker)
    for (lp, rp), truth in zip(ds.pairs, ds.truth):
        tracker.reset()
        res = tracker.track(cv2.imread(str(lp), cv2.IMREAD_UNCHANGED), cv2.imread(str(rp), cv2.IMREAD_UNCHANGED))
        assert res.ok, (lp.name, res.reason)
        assert res.tip_left is not None and res.T_left_marker is not None
        assert np.linalg.norm(res.tip_left - truth.tip) < 0.25e-3  # half size: 960 x 540
        if coded:  # the code gives the whole rotation
            assert res.roll_known and _rotation_deg(res.T_left_marker[:3, :3], truth.R) < 1.0


@pytest.mark.parametrize("name", ["reference_glossy", "coded_glossy"])
def test_the_highlight_breaks_the_papers_chain_on_the_first_glossy_pair(name: str) -> None:
    ds = load_dataset(DATA / name)
    tracker = MarkerTracker(ds.camera, ds.marker)
    for d in (tracker.detector_left, tracker.detector_right):  # the paper's chain only: no retry
        d.settings = replace(d.settings, max_gaps=0)  # type: ignore[attr-defined]
    lp, rp = ds.pairs[0]
    res = tracker.track(cv2.imread(str(lp), cv2.IMREAD_UNCHANGED), cv2.imread(str(rp), cv2.IMREAD_UNCHANGED))
    assert not res.ok and "no marker" in res.reason  # never a wrong pose, but lost
