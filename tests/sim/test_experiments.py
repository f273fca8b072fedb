"""Experiment runners: a safe stop is reported with what ran before it, and the files are written."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

import wristmark.sim.setup as sim_setup
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.rig.loop.tip_sensors import TipMeasurement, TipSensor
from wristmark.sim.experiments import cube_table, run_cube
from wristmark.sim.setup import load_setup


class BlindAfter:
    """The bench's own sensor for ``n`` frames, then never a marker (as if it left the view)."""

    def __init__(self, inner: TipSensor, n: int) -> None:
        self.n = n
        self.inner = inner

    def measure(self, frame: StereoFrame, axis_hint_world: object = None) -> TipMeasurement:
        self.n -= 1
        return self.inner.measure(frame) if self.n >= 0 else TipMeasurement(False, None, "marker not found")


def _blind_after(n: int):  # type: ignore[no-untyped-def]
    real = sim_setup.make_measurement

    def make(setup, arm, clock, seed):  # type: ignore[no-untyped-def]
        frames, sensor = real(setup, arm, clock, seed)
        return frames, BlindAfter(sensor, n)

    return make


def test_cube_reports_a_safe_stop_and_still_writes_the_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    setup = load_setup()
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise", max_lost_cycles=5))
    monkeypatch.setattr(sim_setup, "make_measurement", _blind_after(60 + 69))  # + the play probe's frames
    res = run_cube(setup, tmp_path, progress=False, duration=6.0)
    c = res["closed_loop"]
    assert "marker lost for 6 cycles" in c["stopped"]
    assert c["lost"] == 6
    assert res["open_loop"]["stopped"] == ""
    assert c["cycles"] > 0 and c["mean_mm"] < 1.0  # statistics of the cycles before the stop
    assert json.loads((tmp_path / "result.json").read_text())["closed_loop"]["stopped"] == c["stopped"]
    assert "stopped safely" in cube_table(res)
    assert (tmp_path / "log.csv").is_file()
