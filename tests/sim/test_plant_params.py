"""PlantParams: defaults are ideal, shipped plant files load, every validation error names its key."""

from __future__ import annotations

from pathlib import Path

import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.sim.plant_params import PlantParams

CONFIGS = CONFIG_DIR


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "plant.yaml"
    path.write_text(text)
    return path


def test_defaults_are_ideal() -> None:
    p = PlantParams()
    assert p.bend_gain == (1.0, 1.0)
    assert p.plane_offset == (0.0, 0.0)
    assert p.stem_coupling == 0.0
    assert p.backlash == (0.0,) * 6
    assert p.actuator_tau == 0.0
    assert p.tip_force == (0.0, 0.0, 0.0)


def test_empty_file_gives_defaults(tmp_path: Path) -> None:
    assert PlantParams.load(_write(tmp_path, "{}\n")) == PlantParams()


def test_ideal_config_is_ideal() -> None:
    assert PlantParams.load(CONFIGS / "plant_ideal.yaml") == PlantParams()


@pytest.mark.parametrize("name", ["plant.yaml", "plant_unseen.yaml"])
def test_shipped_plants_load_and_have_errors(name: str) -> None:
    p = PlantParams.load(CONFIGS / name)
    assert p != PlantParams()
    assert p.actuator_tau > 0.0
    assert any(b > 0.0 for b in p.backlash)


def test_default_and_unseen_plants_differ() -> None:
    a = PlantParams.load(CONFIGS / "plant.yaml")
    b = PlantParams.load(CONFIGS / "plant_unseen.yaml")
    assert a.bend_gain != b.bend_gain and a.plane_offset != b.plane_offset
    assert any(f != 0.0 for f in b.tip_force)


def test_all_keys_round_trip(tmp_path: Path) -> None:
    text = (
        "bend_gain: [0.9, 0.95]\nplane_offset: [0.03, -0.02]\nstem_coupling: 0.2\n"
        "backlash: [0.001, 1.0e-5, 2.0e-5, 3.0e-5, 4.0e-5, 5.0e-5]\nactuator_tau: 0.04\n"
        "tip_force: [0.0, 0.1, -0.2]\nsegment_stiffness: [0.3, 0.1]\n"
    )
    p = PlantParams.load(_write(tmp_path, text))
    assert p.bend_gain == (0.9, 0.95)
    assert p.plane_offset == (0.03, -0.02)
    assert p.stem_coupling == 0.2
    assert p.backlash == (0.001, 1.0e-5, 2.0e-5, 3.0e-5, 4.0e-5, 5.0e-5)
    assert p.actuator_tau == 0.04
    assert p.tip_force == (0.0, 0.1, -0.2)
    assert p.segment_stiffness == (0.3, 0.1)


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("bend_gain: [0.0, 1.0]\n", "bend_gain"),
        ("bend_gain: [1.0, 3.0]\n", "bend_gain"),
        ("bend_gain: [1.0]\n", "bend_gain"),
        ("bend_gain: 1.0\n", "bend_gain"),
        ("plane_offset: [2.0, 0.0]\n", "plane_offset"),
        ("plane_offset: [0.0, x]\n", "plane_offset"),
        ("stem_coupling: -0.1\n", "stem_coupling"),
        ("stem_coupling: 5.0\n", "stem_coupling"),
        ("stem_coupling: .nan\n", "stem_coupling"),
        ("backlash: [0.0, 0.0, -1.0e-5, 0.0, 0.0, 0.0]\n", "backlash"),
        ("backlash: [0.0, 0.0, 0.0]\n", "backlash"),
        ("actuator_tau: -0.01\n", "actuator_tau"),
        ("actuator_tau: true\n", "actuator_tau"),
        ("tip_force: [0.0, 0.0]\n", "tip_force"),
        ("tip_force: [0.0, 0.0, .inf]\n", "tip_force"),
        ("segment_stiffness: [0.0, 0.1]\n", "segment_stiffness"),
        ("segment_stiffness: [0.1, -0.1]\n", "segment_stiffness"),
        ("bend_gains: [1.0, 1.0]\n", "bend_gains"),
    ],
)
def test_validation_errors_name_key_and_file(tmp_path: Path, text: str, key: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError) as info:  # the lengths are checked against the arm: the reference arm's
        PlantParams.load(path).for_arm(2, 6, str(path))
    msg = str(info.value)
    assert key in msg
    assert str(path) in msg
    assert "\n" not in msg


def test_not_a_mapping(tmp_path: Path) -> None:
    with pytest.raises(ConfigError):
        PlantParams.load(_write(tmp_path, "- 1\n- 2\n"))


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError):
        PlantParams.load(tmp_path / "nope.yaml")
