"""``wristmark render`` end to end, and its one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.models.arm_spec import home_psi, load_arm
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.robot_params import HOME_PSI
from wristmark.sim.dataset import load_dataset

TENDON3 = CONFIG_DIR / "robots" / "tendon3.yaml"


def test_render_one_pair_end_to_end(tmp_path: Path, capsys) -> None:
    out = tmp_path / "ds"
    assert main(["render", "--out", str(out), "--pairs", "1", "--seed", "3", "--scale", "0.25", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["pairs"] == 1
    ds = load_dataset(out)
    assert len(ds.pairs) == 1 and ds.camera.image_size == (480, 270)
    vis = [c for c in ds.truth[0].corners_left if c.cos_view > 0.3]
    assert len(vis) >= 3


def test_render_given_psi_and_file(tmp_path: Path) -> None:
    f = tmp_path / "psi.txt"
    f.write_text("# phi d theta1 delta1 theta2 delta2\n" + " ".join(map(str, HOME_PSI)) + "\n")
    out = tmp_path / "ds"
    args = ["render", "--out", str(out), "--scale", "0.25", "--noise", "none", "--jpeg", "90", "--motion-blur", "2"]
    assert main([*args, "--psi", *map(str, HOME_PSI), "--psi-file", str(f)]) == 0
    ds = load_dataset(out)
    assert len(ds.truth) == 2
    np.testing.assert_allclose(ds.truth[0].tip, ds.truth[1].tip, atol=1e-15)


def test_render_a_glossy_sleeve(tmp_path: Path) -> None:
    # the same pose matte and glossy: the laminate only adds light (a highlight, clipped)
    import cv2

    psi = ["--psi", "0.0942", "0.0373", "0.554", "0.2658", "0.9152", "-0.2277"]  # sleeve square to the view
    base = ["render", "--scale", "0.5", "--noise", "none", *psi]
    assert main([*base, "--out", str(tmp_path / "matte")]) == 0
    assert main([*base, "--out", str(tmp_path / "gloss"), "--sleeve-specular", "0.04", "--sleeve-roughness", "0.05",
                 "--light-offset", "0.002"]) == 0
    a, b = (cv2.imread(str(load_dataset(tmp_path / d).pairs[0][0])).astype(int) for d in ("matte", "gloss"))
    assert (b - a).min() >= 0 and np.count_nonzero((b - a).max(axis=2) > 40) > 10


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--pairs", "0"], "--pairs"),
        (["--jpeg", "0"], "--jpeg"),
        (["--motion-blur", "-1"], "--motion-blur"),
        (["--noise", "loud"], "invalid choice"),
        (["--calib", "/nonexistent/c.yaml"], "not found"),
        (["--psi", "0", "0.04", "3.0", "0", "0.9", "0"], "theta1"),
        (["--psi-file", "/nonexistent/psi.txt"], "psi file not found"),
        (["--psi", "0", "0.04", "0.7", "0", "0.9", "0", "--pairs", "3"], "disagrees"),
        (["--sleeve-specular", "2"], "--sleeve-specular"),
        (["--sleeve-roughness", "0"], "--sleeve-roughness"),
        (["--light-offset", "0.5"], "--light-offset"),
        (["--psi", "0", "0.04", "0.7", "0", "0.9"], "expected 6 values (phi d theta1 delta1 theta2 delta2)"),
        (["--robot", str(TENDON3), "--psi", "0", "0.04", "0.7", "0", "0.9", "0"],
         "expected 7 values (d theta1 delta1 theta2 delta2 theta3 delta3)"),
    ],
)
def test_bad_options_give_one_line_errors(tmp_path: Path, extra: list[str], needle: str) -> None:
    cmd = [sys.executable, "-m", "wristmark", "render", "--out", str(tmp_path / "x"), "--scale", "0.25", *extra]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=Path(__file__).resolve().parents[2], timeout=120)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], p.stderr
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())  # nothing written


def test_render_takes_a_format2_arms_n_values_of_psi(tmp_path: Path) -> None:
    """--robot tendon3.yaml --psi with its 7 values (and a psi file of 7 per line): the pair shows
    that configuration (the truth's tip is the arm's forward kinematics at it, in the left camera)."""
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.models.kinematics import forward_kinematics

    arm = load_arm(TENDON3)
    q = home_psi(arm)
    f = tmp_path / "psi.txt"
    f.write_text("# d theta1 delta1 theta2 delta2 theta3 delta3\n" + ", ".join(map(str, q)) + "\n")
    out = tmp_path / "ds"
    assert main(["render", "--robot", str(TENDON3), "--out", str(out), "--scale", "0.25", "--noise", "none",
                 "--psi", *map(str, q), "--psi-file", str(f)]) == 0
    ds = load_dataset(out)
    assert len(ds.truth) == 2
    W = np.asarray(load_calibration(out / "calib.yaml").T_world_left)
    tip_left = np.linalg.inv(W) @ np.r_[forward_kinematics(arm, q).tip, 1.0]
    np.testing.assert_allclose(ds.truth[0].tip, tip_left[:3], atol=1e-9)
    np.testing.assert_allclose(ds.truth[1].tip, ds.truth[0].tip, atol=1e-15)
