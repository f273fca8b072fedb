"""examples/ runs in CI: each script in its fast mode as its own process, from a folder outside
the checkout, and its output checked; and the examples use only the public API (names in the
``__all__`` of ``wristmark`` or one of its packages, never a deep import)."""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
PUBLIC_PACKAGES = {"wristmark", *(f"wristmark.{p}" for p in ("models", "cvs", "solvers", "rig", "viz", "sim", "cli"))}


def run_example(name: str, tmp_path: Path, timeout: float = 240) -> list[dict]:
    """Run examples/NAME --fast with cwd = tmp_path; its stdout's JSON lines."""
    r = subprocess.run([sys.executable, str(EXAMPLES / name), "--fast"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=timeout)
    assert r.returncode == 0, r.stderr[-2000:]
    return [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]


def test_every_example_is_tested() -> None:
    tested = {"kinematics.py", "track_video.py", "virtual_lab.py", "register.py", "own_trajectory.py"}
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.py")), ids=lambda p: p.name)
def test_example_uses_only_the_public_api(path: Path) -> None:
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "wristmark":
                    assert alias.name in PUBLIC_PACKAGES, f"{path.name}: deep import {alias.name}"
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "wristmark":
            assert node.module in PUBLIC_PACKAGES, f"{path.name}: deep import from {node.module}"
            public = importlib.import_module(node.module).__all__
            for alias in node.names:
                assert alias.name in public, f"{path.name}: {node.module}.{alias.name} is not public"


def test_kinematics_example(tmp_path: Path) -> None:
    (out,) = run_example("kinematics.py", tmp_path)
    assert out["jacobian_shape"] == [6, 6]
    assert out["jacobian_fd_max_error"] < 1e-8  # central differences, step 1e-6
    assert out["ik_converged"] and out["ik_error_m"] < 1e-6
    assert max(abs(a - b) for a, b in zip(out["ik_tip_world_m"], out["ik_target_world_m"])) < 1e-6
    assert 0.05 < out["tip_world_m"][2] < 0.25  # the tip is in front of the incision, along z_w [m]


def test_track_video_example(tmp_path: Path) -> None:
    lines = run_example("track_video.py", tmp_path)
    frames, summary = lines[:-1], lines[-1]
    assert [f["frame"] for f in frames] == list(range(8))
    assert summary["frames"] == 8 and summary["tracked"] >= 7
    assert summary["tip_error_mean_mm"] < 0.5 and summary["tip_error_max_mm"] < 1.5
    assert not list(tmp_path.iterdir())  # the video went to a temporary folder, removed


@pytest.mark.slow
def test_register_example(tmp_path: Path) -> None:
    (out,) = run_example("register.py", tmp_path)
    assert out["visits"] == 12 and out["tracked_visits"] >= 10
    before, after = out["calibration_error"], out["registered_error"]
    assert before["translation_mm"] > 5  # the plant file moves the camera 5.8 mm / 3.2 deg
    assert after["translation_mm"] < before["translation_mm"] / 2
    assert after["rotation_deg"] < before["rotation_deg"] / 2


@pytest.mark.slow
@pytest.mark.network
def test_virtual_lab_example(tmp_path: Path) -> None:
    (out,) = run_example("virtual_lab.py", tmp_path)
    assert out["stopped"] == ""
    assert out["link"].startswith("/dev/") and out["camera"].startswith("http://127.0.0.1:")
    assert out["cycles"] >= 20  # 2 s of the cube at the 60 ms cycle, plus settling
    held = {k: out[k] for k in ("cycles_lost", "cycles_rejected", "cycles_without_frame", "cycles_reused",
                                "cycles_skipped", "realtime_priority")}  # shown on failure
    assert out["true_error_mean_mm"] < 2.0 and out["vision_error_mean_mm"] < 2.0, held


def test_own_trajectory_example(tmp_path: Path) -> None:
    (out,) = run_example("own_trajectory.py", tmp_path)
    closed, open_loop = out["closed_loop"], out["open_loop"]
    assert out["path"]["waypoints"] == 73 and 2.0 < out["path"]["duration_s"] < 5.0  # 8 x 6 mm at 10 mm/s
    assert closed["stopped"] == "" and closed["cycles"] >= 30 and closed["cycles"] == open_loop["cycles"]
    assert closed["mean_mm"] < 1.0 and closed["max_mm"] < 2.0  # vision in the loop
    assert closed["mean_mm"] < 0.5 * open_loop["mean_mm"]  # what the loop buys over the model alone
    assert closed["vision_vs_true_mean_mm"] < 0.5
    assert not list(tmp_path.iterdir())  # nothing written
