"""Validated YAML configuration: every documented error names the key and the file."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.config_io import from_mapping, load_config, load_yaml, save_yaml, to_mapping
from wristmark.models.errors import ConfigError, WristmarkError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams

CONFIGS = CONFIG_DIR


def _write(tmp_path: Path, text: str, name: str = "cfg.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _error(loader, path: Path) -> str:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError) as e:
        loader(path)
    msg = str(e.value)
    assert "\n" not in msg, "errors are one line"
    assert str(path) in msg, "errors name the file"
    assert isinstance(e.value, WristmarkError) and isinstance(e.value, ValueError)
    return msg


def test_shipped_configs_load_and_match_defaults() -> None:
    assert RobotParams.load(CONFIGS / "robot.yaml") == RobotParams()
    assert MarkerModel.load(CONFIGS / "marker.yaml") == MarkerModel()


@pytest.mark.parametrize(
    "text, words",
    [
        ("bogus: 1\n", ["unknown key 'bogus'", "segment_lengths"]),
        ("segment_lengths: [0.1, 0.02, 0.03]\n", ["'segment_lengths'", "2 entries", "got 3"]),
        ("segment_lengths: 0.1\n", ["'segment_lengths'", "list"]),
        ("max_velocity: [1, 1, 1, 1, 1]\n", ["'max_velocity'", "6 entries"]),
        ("segment_lengths: [0.1, 0.0]\n", ["'segment_lengths[1]'", "> 0"]),
        ("segment_lengths: [-0.1, 0.02]\n", ["'segment_lengths[0]'", "> 0"]),
        ("backbone_radius: [0.0025, -1]\n", ["'backbone_radius[1]'"]),
        ("rigid_length: -0.01\n", ["'rigid_length'", "positive"]),
        ("outer_diameter: 0\n", ["'outer_diameter'"]),
        ("phi_range: [1.0, -1.0]\n", ["'phi_range'", "inverted"]),
        ("d_range: [0.1, 0.1]\n", ["'d_range'", "inverted or empty"]),
        ("theta_max: [1.0, 4.0]\n", ["'theta_max[1]'", "(0, pi]"]),
        ("theta_max: [0.0, 1.0]\n", ["'theta_max[0]'"]),
        ("tip_offset: abc\n", ["'tip_offset'", "number"]),
        ("tip_offset: true\n", ["'tip_offset'", "number"]),
        ("tip_offset: .nan\n", ["'tip_offset'", "finite"]),
        ("segment_lengths: [0.1, .inf]\n", ["'segment_lengths[1]'", "finite"]),
        ("segment_lengths: [0.1, x]\n", ["'segment_lengths[1]'", "number"]),
    ],
)
def test_robot_params_errors(tmp_path: Path, text: str, words: list[str]) -> None:
    msg = _error(RobotParams.load, _write(tmp_path, text))
    for w in words:
        assert w in msg


def test_missing_file(tmp_path: Path) -> None:
    msg = _error(RobotParams.load, tmp_path / "nope.yaml")
    assert "file not found" in msg


def test_bad_yaml(tmp_path: Path) -> None:
    msg = _error(RobotParams.load, _write(tmp_path, "segment_lengths: [0.1, 0.02\n"))
    assert "not valid YAML" in msg


def test_not_a_mapping(tmp_path: Path) -> None:
    msg = _error(RobotParams.load, _write(tmp_path, "- 1\n- 2\n"))
    assert "mapping" in msg and "list" in msg


def test_empty_file_gives_defaults_and_robot_key_is_accepted(tmp_path: Path) -> None:
    assert RobotParams.load(_write(tmp_path, "")) == RobotParams()
    p = RobotParams.load(_write(tmp_path, "robot:\n  tip_offset: 0.02\n", "r.yaml"))
    assert p.tip_offset == 0.02 and p.segment_lengths == (0.1, 0.02)


@pytest.mark.parametrize(
    "text, words",
    [
        ("columns: 7\n", ["'columns'", "even integer"]),
        ("columns: 2\n", ["'columns'", ">= 4"]),
        ("columns: 12.5\n", ["'columns'", "integer"]),
        ("radius: 0\n", ["'radius'", "> 0"]),
        ("row_height: -0.001\n", ["'row_height'", "> 0"]),
        ("tip_offset: -0.01\n", ["'tip_offset'", ">= 0"]),
        ("colour: red\n", ["unknown key 'colour'", "radius"]),
    ],
)
def test_marker_errors(tmp_path: Path, text: str, words: list[str]) -> None:
    msg = _error(MarkerModel.load, _write(tmp_path, text, "marker.yaml"))
    for w in words:
        assert w in msg


@dataclass(frozen=True)
class _Inner:
    gain: float = 1.0


@dataclass(frozen=True)
class _Outer:
    name: str = "x"
    enabled: bool = False
    count: int = 1
    values: tuple[float, ...] = ()
    inner: _Inner = field(default_factory=_Inner)
    limit: float | None = None


def test_from_mapping_types_and_nesting() -> None:
    o = from_mapping(
        _Outer,
        {
            "name": "a",
            "enabled": True,
            "count": 3,
            "values": [1, 2.5],
            "inner": {"gain": 2},
            "limit": None,
        },
        "src.yaml",
    )
    assert o == _Outer("a", True, 3, (1.0, 2.5), _Inner(2.0), None)
    assert isinstance(o.values[0], float)
    assert to_mapping(o) == {
        "name": "a",
        "enabled": True,
        "count": 3,
        "values": [1.0, 2.5],
        "inner": {"gain": 2.0},
        "limit": None,
    }


@pytest.mark.parametrize(
    "data, words",
    [
        ({"inner": {"gian": 1}}, ["unknown key 'inner.gian'"]),
        ({"inner": 3}, ["'inner'", "mapping"]),
        ({"enabled": "yes"}, ["'enabled'", "true or false"]),
        ({"count": True}, ["'count'", "integer"]),
        ({"name": 5}, ["'name'", "string"]),
        ({"values": [1, "a"]}, ["'values[1]'", "number"]),
        ({"limit": "high"}, ["'limit'", "number"]),
    ],
)
def test_from_mapping_errors(data: dict, words: list[str]) -> None:
    with pytest.raises(ConfigError) as e:
        from_mapping(_Outer, data, "src.yaml")
    assert str(e.value).startswith("src.yaml: ")
    for w in words:
        assert w in str(e.value)


def test_save_and_load_round_trip(tmp_path: Path) -> None:
    p = RobotParams(segment_lengths=(0.09, 0.025), theta_max=(1.0, math.pi))
    path = tmp_path / "robot.yaml"
    save_yaml(path, to_mapping(p))
    assert load_config(RobotParams, path) == p
    assert load_yaml(path)["segment_lengths"] == [0.09, 0.025]
