"""RigConfig loading and validation."""

from pathlib import Path

import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.rig.loop.rig_config import RigConfig

CONFIGS = CONFIG_DIR


def test_default_file_loads_and_matches_paper_cycle() -> None:
    cfg = RigConfig.load(CONFIGS / "rig.yaml")
    assert cfg.control_dt == pytest.approx(0.060)
    assert cfg.sensor == "vision"  # the real pipeline is the default


@pytest.mark.parametrize(
    "text, words",
    [
        ("control_dt: 0\n", ["control_dt", "> 0"]),
        ("control_dt: 0.03\nvision_latency: 0.05\n", ["vision_latency", "shorter"]),
        ("sensor: magic\n", ["sensor", "vision"]),
        ("render_noise: loud\n", ["render_noise"]),
        ("bogus: 1\n", ["unknown key 'bogus'"]),
        ("gate: [1, 2]\n", ["gate", "number"]),
        ("max_lost_cycles: 0\n", ["max_lost_cycles"]),
        ("frame_age: -0.01\n", ["frame_age", ">= 0"]),
        ("frame_age: 1.5\n", ["frame_age", "at most 1 s"]),
        ("frame_age: 0.1\nsensor: truth-noise\n", ["frame_age", "vision"]),
        ("delay_compensation_learn_window: -1\n", ["delay_compensation_learn_window", ">= 0"]),
        ("delay_compensation_learn_window: 1000\n", ["delay_compensation_learn_window", "at most 600 s"]),
        ("delay_compensation_learn_window: .nan\n", ["delay_compensation_learn_window", "finite"]),
    ],
)
def test_validation_errors_name_key_and_file(tmp_path: Path, text: str, words: list[str]) -> None:
    f = tmp_path / "rig.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        RigConfig.load(f)
    msg = str(e.value)
    assert str(f) in msg and "\n" not in msg
    for w in words:
        assert w in msg
