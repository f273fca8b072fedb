"""The cube walked with vision in the loop on a glossy sleeve (configs/rig_glossy.yaml): the
highlight stripe of the endoscope's own light never stops the loop (docs/notes/highlight-stripe.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from wristmark.models.config_files import default_config
from wristmark.sim.experiments import run_cube
from wristmark.sim.setup import load_setup


@pytest.mark.slow
def test_a_short_cube_walk_on_a_glossy_sleeve_never_stops(tmp_path: Path) -> None:
    setup = load_setup(rig=str(default_config("rig_glossy.yaml")))
    assert setup.rig.sleeve_specular > 0 and setup.rig.sensor == "vision"
    res = run_cube(setup, tmp_path, progress=False, duration=8.0)
    c = res["closed_loop"]
    assert c["stopped"] == "" and res["open_loop"]["stopped"] == ""
    assert c["mean_mm"] <= 0.3 and c["max_mm"] <= 1.0
    assert c["lost"] <= 0.02 * c["cycles"]
