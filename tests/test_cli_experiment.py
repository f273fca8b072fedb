"""`wristmark experiment` as a user runs it (subprocess): a short cube run with the vision
pipeline in the loop (rendered stereo pairs -> tracker -> controller), and its error messages."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def wristmark(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "wristmark", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def short_cube(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, subprocess.CompletedProcess[str]]:
    out = tmp_path_factory.mktemp("cube")
    r = wristmark("experiment", "cube", "--duration", "1.2", "--out", str(out / "run"),
                  "--json", str(out / "result.json"), "--no-progress", timeout=240)
    assert r.returncode == 0, r.stderr
    return out, json.loads((out / "result.json").read_text()), r


def test_short_cube_with_vision_in_the_loop_closes_the_loop(short_cube: tuple) -> None:
    _, res, _ = short_cube
    assert res["sensor"] == "vision"  # the default path renders and tracks pixels
    o, c = res["open_loop"], res["closed_loop"]
    assert o["mean_mm"] > 1.0  # the default plant's errors are real ...
    assert c["mean_mm"] < 0.5  # ... and the loop removes most of them
    assert res["ratio"] == pytest.approx(c["mean_mm"] / o["mean_mm"])
    assert res["ratio"] < 0.3
    m = c["measurements"]
    assert m["accepted"] >= 0.9 * (m["accepted"] + m["lost_or_rejected"])
    assert c["vision_vs_true"]["mean_mm"] < 0.3  # the tracker's own error on rendered images
    assert c["vision_ms_median"] > 0


def test_run_folder_holds_config_log_results_and_plots(short_cube: tuple) -> None:
    out, res, r = short_cube
    run = out / "run"
    for name in ("config.json", "log.csv", "result.json", "results.md"):
        assert (run / name).is_file(), name
    assert list(run.glob("*.png")), "no plots written"
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["rig"]["sensor"] == "vision" and cfg["controller"]["kind"] == res["controller"]
    with open(run / "log.csv") as f:
        rows = list(csv.DictReader(f))
    phases = {row["phase"] for row in rows}
    assert {"open_loop", "closed_loop"} <= phases
    assert "paper (Fig. 8)" in r.stdout and "wristmark" in r.stdout


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--duration", "-1"], ["--duration"]),
        (["--controller", "bogus"], ["bogus", "paper", "qp"]),
        (["--plant", "no/such/plant.yaml"], ["plant.yaml"]),
        (["--dt", "0"], ["--dt", "[0.001, 1]"]),
        (["--point", "0", "0", "0.1"], ["--point", "point experiment"]),
    ],
)
def test_bad_options_give_one_line_errors(tmp_path: Path, args: list[str], words: list[str]) -> None:
    r = wristmark("experiment", "cube", "--sensor", "truth-noise", "--out", str(tmp_path / "x"), *args)
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert "error" in last
    for w in words:
        assert w in last, last
    assert not (tmp_path / "x" / "log.csv").exists()  # nothing ran


def test_view_prints_the_url_and_the_replay_command(tmp_path: Path) -> None:
    r = wristmark("experiment", "cube", "--sensor", "truth-noise", "--duration", "1", "--view", "--no-progress",
                  "--out", str(tmp_path / "run"), timeout=120)
    assert r.returncode == 0, r.stderr
    assert "live 3D view: open http://" in r.stderr
    assert f"wristmark view {tmp_path / 'run'}" in r.stderr
    assert (tmp_path / "run" / "log.csv").is_file()
