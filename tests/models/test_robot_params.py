"""models/robot_params.py: the tip offset is the marker's, defined once (docs/design.md: the marker
file's ``tip_offset``); a robot file that states a different one is refused, naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.models.config_files import default_config
from wristmark.models.config_io import load_yaml
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams, load_robot


def test_the_shipped_files_define_the_tip_offset_once() -> None:
    assert "tip_offset" not in load_yaml(default_config("robot.yaml"))
    for name in ("marker.yaml", "marker_coded.yaml"):
        assert "tip_offset" in load_yaml(default_config(name)), name


@pytest.mark.parametrize("robot", [None, "shipped"])
def test_the_robot_takes_the_markers_tip_offset(robot: str | None) -> None:
    marker = MarkerModel(tip_offset=0.021)
    params = load_robot(default_config("robot.yaml") if robot else None, marker)
    assert params.tip_offset == 0.021
    fr = forward_kinematics(params, HOME_PSI)  # the tip lies tip_offset along z of {wm}
    np.testing.assert_allclose(fr.tip, fr.T_world_marker[:3, 3] + 0.021 * fr.T_world_marker[:3, 2], atol=1e-15)


def test_a_robot_file_stating_another_tip_offset_is_refused_naming_it(tmp_path: Path) -> None:
    bad = tmp_path / "my_robot.yaml"
    bad.write_text("robot:\n  tip_offset: 0.02\n")
    with pytest.raises(ConfigError) as e:
        load_robot(bad, MarkerModel(tip_offset=0.015))
    msg = str(e.value)
    assert str(bad) in msg and "marker" in msg and "0.02" in msg and "0.015" in msg and "\n" not in msg


def test_a_robot_file_stating_the_same_tip_offset_is_accepted(tmp_path: Path) -> None:
    same = tmp_path / "robot.yaml"
    same.write_text("tip_offset: 0.017\nrigid_length: 0.011\n")
    params = load_robot(same, MarkerModel(tip_offset=0.017))
    assert params == RobotParams(tip_offset=0.017, rigid_length=0.011)


def test_the_command_line_refuses_the_mismatch_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "robot_tip.yaml"
    bad.write_text("tip_offset: 0.03\n")
    code = main(["render", "--out", str(tmp_path / "out"), "--pairs", "1", "--robot", str(bad)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and str(bad) in err[0] and "tip_offset" in err[0]
    assert not (tmp_path / "out").exists()
