"""The identified-arm file (models/model_file.py): written with the fit's report, read back as a
plant, and a plain plant file refused with one line naming the cause."""

from __future__ import annotations

from pathlib import Path

import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.models.model_file import load_model, save_model
from wristmark.models.plant_params import PlantParams


def test_round_trip_keeps_the_fitted_values(tmp_path: Path) -> None:
    plant = PlantParams(bend_gain=(1.02, 0.9), plane_offset=(0.01, -0.03), stem_coupling=0.041,
                        backlash=(0.005, 1e-4, 5e-5, 5e-5, 5e-5, 5e-5), actuator_tau=0.05)
    save_model(tmp_path / "m.yaml", plant, {"rms_m": 5e-5, "poses": 40, "not_separable": ["a ~ b"]})
    text = (tmp_path / "m.yaml").read_text()
    assert "rms_m" in text and "poses: 40" in text
    assert load_model(tmp_path / "m.yaml") == plant


def test_a_plant_file_is_not_a_model() -> None:
    with pytest.raises(ConfigError, match="not a model file"):
        load_model(CONFIG_DIR / "plant_unseen.yaml")


def test_a_bad_value_names_the_key(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text("rms_m: 0.0001\nposes: 3\nbend_gain: [3.0, 1.0]\n")
    with pytest.raises(ConfigError, match="bend_gain"):
        load_model(tmp_path / "m.yaml")
