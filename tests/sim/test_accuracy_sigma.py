"""The accuracy experiment (paper IV.B) records each position's tip sigma as the tracker reports
it (TipMeasurement.tip_sigma_m, from TrackResult.tip_sigma_m): every tracked estimate lies
within 3 of it of the true tip."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wristmark.sim.experiments import run_accuracy
from wristmark.sim.setup import load_setup


def test_each_position_records_its_tip_sigma_and_lies_within_three_of_it(tmp_path: Path) -> None:
    rows = run_accuracy(load_setup(), tmp_path, n=4, progress=False)["positions_detail"]
    assert len(rows) == 4 and all(r["ok"] for r in rows)
    for r in rows:
        sigma = r["tip_sigma_mm"]
        assert sigma is not None and 0.0 < sigma < 0.5
        assert 1e3 * np.linalg.norm(np.subtract(r["estimate"], r["true"])) < 3.0 * sigma
