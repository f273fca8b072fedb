"""After ``experiment --view`` the live URL is dead: the command says so and gives the replay
command first (issue 17, item 5); ``--host`` reaches the live view."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.network]

ROOT = Path(__file__).resolve().parents[2]


def test_experiment_view_says_the_url_closed_and_prints_the_replay_command(tmp_path: Path) -> None:
    run = tmp_path / "run"
    p = subprocess.run([sys.executable, "-m", "wristmark", "experiment", "cube", "--sensor", "truth-noise",
                        "--duration", "0.3", "--view", "--host", "127.0.0.2", "--no-progress", "--out", str(run)],
                       cwd=ROOT, capture_output=True, text=True, timeout=180)
    assert p.returncode == 0, p.stderr
    lines = p.stderr.strip().splitlines()
    url_line = next(i for i, ln in enumerate(lines) if ln.startswith("live 3D view: open http://"))
    url = lines[url_line].split("open ", 1)[1]
    assert any("also listens on 127.0.0.2" in ln for ln in lines[:url_line]), lines  # --host reached the view
    assert f"then replay the run: wristmark view {run}" in lines[url_line + 1]
    replay = next(i for i, ln in enumerate(lines) if ln == f"replay in the browser: wristmark view {run}")
    assert replay > url_line and lines[replay + 1] == f"(the live view at {url} has closed with the run)"
    # (not probed afterwards: other runs on this machine may take the freed port at once)
