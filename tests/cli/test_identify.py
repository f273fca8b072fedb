"""`wristmark identify` as a user runs it (subprocess): a short excitation on the simulated bench
with the vision in the loop writes a model file, offline from its record gives the same fit, and
bad input is one line with exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
UNSEEN = "wristmark/configs/plant_unseen.yaml"


def wristmark(*args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "wristmark", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.slow
def test_identify_on_the_bench_then_offline_from_its_record(tmp_path: Path) -> None:
    r = wristmark("identify", "--plant", UNSEEN, "--poses", "12", "--out", str(tmp_path / "m.yaml"),
                  "--log", str(tmp_path / "log"), "--no-progress")
    assert r.returncode == 0, r.stderr
    model = yaml.safe_load((tmp_path / "m.yaml").read_text())
    assert model["poses"] >= 12 and model["rms_m"] < 3e-4
    assert model["bend_gain"] == pytest.approx([1.06, 0.88], abs=0.02)  # the unseen plant's truth
    assert any("stem-rotation" in note for note in model["not_separable"])
    off = wristmark("identify", "--from-log", str(tmp_path / "log"), "--out", str(tmp_path / "m2.yaml"))
    assert off.returncode == 0, off.stderr
    again = yaml.safe_load((tmp_path / "m2.yaml").read_text())
    assert again["bend_gain"] == pytest.approx(model["bend_gain"], abs=1e-9)


@pytest.mark.parametrize("args, cause", [
    (("--serial", "/dev/null", "--camera", "0"), "--serial/--camera"),
    (("--from-log", "nowhere"), "--from-log: no excitation.npz"),
    (("--plant", "missing.yaml"), "missing.yaml"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, args: tuple[str, ...], cause: str) -> None:
    r = wristmark("identify", *args, "--out", str(tmp_path / "m.yaml"), timeout=60)
    assert r.returncode == 2
    assert cause in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "m.yaml").exists()


def test_experiment_refuses_a_plant_file_as_model() -> None:
    r = wristmark("experiment", "cube", "--model", UNSEEN, "--duration", "0.5", timeout=60)
    assert r.returncode == 2
    assert "not a model file" in r.stderr and len(r.stderr.strip().splitlines()) == 1
