"""wristmark.models.config_files: the shipped configs are package data; a user's file wins."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from wristmark.models.config_files import CONFIG_DIR, default_config, find_config, shipped_configs
from wristmark.models.config_io import load_yaml
from wristmark.models.errors import ConfigError
from wristmark.models.robot_params import RobotParams


def test_the_shipped_configs_sit_inside_the_package() -> None:
    assert CONFIG_DIR.parent.name == "wristmark" and (CONFIG_DIR.parent / "__init__.py").is_file()
    names = shipped_configs()
    for name in ("robot.yaml", "marker.yaml", "marker_coded.yaml", "camera.yaml", "plant_unseen.yaml",
                 "sweeps/latency_backlash.yaml"):
        assert name in names
    assert default_config("robot.yaml") == CONFIG_DIR / "robot.yaml"


def test_a_missing_path_named_like_a_shipped_file_is_that_file(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    for given in ("configs/plant_unseen.yaml", "plant_unseen.yaml"):
        assert find_config(given) == CONFIG_DIR / "plant_unseen.yaml"
    assert find_config("configs/sweeps/latency_backlash.yaml") == CONFIG_DIR / "sweeps" / "latency_backlash.yaml"
    assert RobotParams.load("configs/robot.yaml") == RobotParams.load(CONFIG_DIR / "robot.yaml")


def test_a_users_own_file_always_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "configs").mkdir()
    own = tmp_path / "configs" / "robot.yaml"
    own.write_text("mine: 1\n")
    assert find_config("configs/robot.yaml") == Path("configs/robot.yaml")
    assert load_yaml("configs/robot.yaml") == {"mine": 1}


def test_an_unknown_name_stays_missing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert find_config("configs/nope.yaml") == Path("configs/nope.yaml")
    assert find_config("elsewhere/robot.yaml") == Path("elsewhere/robot.yaml")  # only configs/ or a bare name
    with pytest.raises(ConfigError, match="not found"):
        load_yaml("configs/nope.yaml")


def test_commands_find_the_shipped_files_from_any_folder(tmp_path: Path) -> None:
    """README commands name configs/...; run from a folder without one they still work."""
    out = tmp_path / "sleeve.svg"
    p = subprocess.run([sys.executable, "-m", "wristmark", "marker", "print", "--marker", "configs/marker_coded.yaml",
                        "--out", str(out)], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert out.read_text().lstrip().startswith("<") and "svg" in out.read_text()[:400]
    p = subprocess.run([sys.executable, "-m", "wristmark", "marker", "print", "--marker", "configs/nope.yaml",
                        "--out", str(tmp_path / "x.svg")], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "configs/nope.yaml" in p.stderr and len(p.stderr.strip().splitlines()) == 1
