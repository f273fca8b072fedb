"""`wristmark fk` on any arm: format-2 robot files, n values of psi, the actuator coordinates;
the reference arm's tip, marker and Jacobian exactly as models.kinematics gives them. And
`wristmark urdf` for a format-2 file; other commands refuse one in a line saying where it is read."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wristmark.cli import main as cli
from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_actuation import arm_actuators
from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian
from wristmark.models.arm_spec import load_arm
from wristmark.models.arm_urdf import generate_arm_urdf
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import forward_kinematics, tip_jacobian
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams, load_robot
from wristmark.models.urdf import generate_urdf

ROOT = Path(__file__).resolve().parents[2]
ROBOTS = CONFIG_DIR / "robots"


def fk(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["fk", *argv])
    return code, out.getvalue(), err.getvalue()


def _today(psi: list[float]) -> dict:  # type: ignore[type-arg]
    """The JSON of today's `wristmark fk` (models.kinematics), without the new actuators."""
    p = RobotParams()
    fr = forward_kinematics(p, psi)
    return {"tip": fr.tip.tolist(),
            "marker": {"R": fr.T_world_marker[:3, :3].tolist(), "t": fr.T_world_marker[:3, 3].tolist()},
            "jacobian": tip_jacobian(p, psi, fr).tolist()}


PSIS = [[0.0, 0.04, 0.7, 0.0, 0.9, 0.0], [0.3, 0.04, 0.7, -1.2, 1.1, 2.5], [-3.0, 0.15, 0.0, 2.0, 1e-9, -0.5],
        [1.0, 0.0, 1.5, 3.1, 2.0, -3.1], [-0.0, -0.0, 0.19, -0.0, 0.21, 0.0]]


@pytest.mark.parametrize("robot", [None, "configs/robot.yaml", str(ROBOTS / "paper.yaml")])
@pytest.mark.parametrize("psi", PSIS)
def test_the_reference_arm_prints_todays_numbers(robot: str | None, psi: list[float]) -> None:
    code, out, err = fk("--psi", *map(repr, psi), "--json", *(["--robot", robot] if robot else []))
    assert code == 0, err
    res = json.loads(out)
    actuators = res.pop("actuators")
    assert json.dumps(res) == json.dumps(_today(psi))  # the same text: bit for bit
    np.testing.assert_allclose(actuators, actuators_from_psi(RobotParams(), psi), rtol=0, atol=1e-15)


@pytest.mark.parametrize("name, psi", [("tendon3.yaml", [0.03, 0.5, 0.0, 0.4, 1.0, 0.3, -2.0]),
                                       ("single_tendon.yaml", [0.2, 0.05, 1.0, -0.3]),
                                       ("planar.yaml", [0.1, 0.04, -0.7, 0.9])])
def test_format_2_arms(name: str, psi: list[float]) -> None:
    spec = load_arm(ROBOTS / name)
    code, out, err = fk("--robot", str(ROBOTS / name), "--psi", *map(repr, psi), "--json")
    assert code == 0, err
    res = json.loads(out)
    fr = arm_frames(spec, psi)
    assert np.array(res["jacobian"]).shape == (6, spec.n)
    np.testing.assert_array_equal(res["jacobian"], arm_tip_jacobian(spec, psi))
    np.testing.assert_array_equal(res["tip"], fr.tip)
    np.testing.assert_array_equal(res["marker"]["R"], fr.T_world_marker[:3, :3])
    np.testing.assert_array_equal(res["marker"]["t"], fr.T_world_marker[:3, 3])
    assert len(res["actuators"]) == spec.m
    np.testing.assert_array_equal(res["actuators"], arm_actuators(spec, psi))


def test_the_count_of_psi_follows_the_robot_file() -> None:
    code, out, err = fk("--robot", str(ROBOTS / "tendon3.yaml"), "--psi", "0", "0", "0", "0", "0", "0")
    assert code == 2 and not out and len(err.strip().splitlines()) == 1
    assert "expected 7 arguments (d theta1 delta1 theta2 delta2 theta3 delta3)" in err and "got 6" in err


def test_a_user_runs_it_on_a_shipped_arm(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "wristmark", "fk", "--robot", "configs/robots/single_tendon.yaml",
                        "--psi", "0", "0.02", "0", "0"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    # straight: 20 + 35 + 5 mm, and the marker's 15 mm tip offset
    assert "[0.000, 0.000, 75.000] mm" in r.stdout


def test_urdf_of_a_format_2_arm(tmp_path: Path) -> None:
    out = tmp_path / "tendon3.urdf"
    code, stdout, err = cli_run("urdf", "--robot", str(ROBOTS / "tendon3.yaml"), "--out", str(out), "--links", "2",
                                "--json")
    assert code == 0, err
    assert json.loads(stdout) == {"urdf": str(out), "links_per_segment": 2}
    text = out.read_text()
    assert text == generate_arm_urdf(load_arm(ROBOTS / "tendon3.yaml"), 2)
    assert 'name="seg3_end"' in text and 'name="phi"' not in text


def test_the_flat_file_still_gives_todays_urdf(tmp_path: Path) -> None:
    out = tmp_path / "arm.urdf"
    code, _, err = cli_run("urdf", "--robot", "configs/robot.yaml", "--out", str(out), "--links", "3")
    assert code == 0, err
    assert out.read_text() == generate_urdf(RobotParams(), 3)


def test_commands_not_yet_wired_refuse_a_format_2_file_in_one_line() -> None:
    """The loop's commands read the robot through RobotParams (load_robot) until the wiring."""
    for load in (RobotParams.load, lambda p: load_robot(p, MarkerModel())):
        with pytest.raises(ConfigError, match="format-2 robot file .* 'wristmark fk' and 'wristmark urdf'") as e:
            load(ROBOTS / "tendon3.yaml")
        assert "\n" not in str(e.value) and str(ROBOTS / "tendon3.yaml") in str(e.value)


def cli_run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(list(argv))
    return code, out.getvalue(), err.getvalue()
