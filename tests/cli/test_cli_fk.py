"""`wristmark fk` and `wristmark urdf` as a user runs them (subprocess)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

from wristmark.cli.main import COMMANDS
from wristmark.models.kinematics import tip_jacobian
from wristmark.models.robot_params import RobotParams
from wristmark_testing.reference_chain import chain

ROOT = Path(__file__).resolve().parents[2]
PARAMS = RobotParams()


def wristmark(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "wristmark", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def _one_line_error(r: subprocess.CompletedProcess[str], *words: str) -> None:
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert "error" in last
    for w in words:
        assert w in last


def test_fk_json_matches_independent_chain() -> None:
    psi = [0.3, 0.04, 0.7, -1.2, 1.1, 2.5]
    r = wristmark("fk", "--psi", *map(str, psi), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    ref = chain({"L1": 0.1, "L2": 0.02, "Lr": 0.01, "lm": 0.005, "lt": 0.015}, np.array(psi))
    np.testing.assert_allclose(out["tip"], ref["tip"][:3, 3], rtol=0, atol=1e-15)  # [m]
    np.testing.assert_allclose(out["marker"]["R"], ref["marker"][:3, :3], rtol=0, atol=1e-14)
    np.testing.assert_allclose(out["marker"]["t"], ref["marker"][:3, 3], rtol=0, atol=1e-15)
    J = np.array(out["jacobian"])
    assert J.shape == (6, 6)
    np.testing.assert_array_equal(J, tip_jacobian(PARAMS, psi))  # JSON floats round-trip


def test_fk_with_robot_file_and_plain_output(tmp_path: Path) -> None:
    robot = tmp_path / "robot.yaml"
    robot.write_text("segment_lengths: [0.05, 0.02]\n")
    r = wristmark("fk", "--psi", "0", "0", "0", "0", "0", "0", "--robot", str(robot))
    assert r.returncode == 0, r.stderr
    # straight: 0.05 + 0.01 + 0.02 + 0.005 + 0.015 m = 100 mm
    assert "[0.000, 0.000, 100.000] mm" in r.stdout


def test_fk_nan_is_a_one_line_error() -> None:
    _one_line_error(wristmark("fk", "--psi", "0", "0", "nan", "0", "0", "0", "--json"), "finite")


def test_fk_wrong_count_is_an_error() -> None:
    _one_line_error(wristmark("fk", "--psi", "0", "0", "0", "0", "0", "--json"), "6 arguments")


def test_fk_bad_robot_file_is_a_one_line_error(tmp_path: Path) -> None:
    robot = tmp_path / "robot.yaml"
    robot.write_text("segment_lengths: [0.05]\n")
    r = wristmark("fk", "--psi", "0", "0", "0", "0", "0", "0", "--robot", str(robot))
    _one_line_error(r, "segment_lengths", str(robot))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


def test_help_lists_the_commands() -> None:
    r = wristmark("--help")
    assert r.returncode == 0
    for name in COMMANDS:
        assert name in r.stdout
    assert {"fk", "urdf", "track", "render", "experiment", "servo", "view"} <= set(COMMANDS)


def test_urdf_writes_a_file_pinocchio_loads(tmp_path: Path) -> None:
    out = tmp_path / "arm.urdf"
    r = wristmark("urdf", "--out", str(out), "--links", "3", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == {"urdf": str(out), "links_per_segment": 3}
    model = pin.buildModelFromUrdf(str(out))
    assert model.nq == 4 * 3 + 8 and model.existFrame("tip")


def test_urdf_errors_are_one_line(tmp_path: Path) -> None:
    r = wristmark("urdf", "--out", str(tmp_path / "a.urdf"), "--links", "0")
    _one_line_error(r, "--links")
    assert len(r.stderr.strip().splitlines()) == 1
    r = wristmark("urdf", "--out", str(tmp_path / "no" / "a.urdf"))
    _one_line_error(r, "cannot write")
    marker = tmp_path / "m.yaml"
    marker.write_text("columns: 5\n")
    r = wristmark("urdf", "--out", str(tmp_path / "a.urdf"), "--marker", str(marker))
    _one_line_error(r, "columns", str(marker))
