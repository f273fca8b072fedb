"""Writes tests/data/scene_run: a small run folder of two arms in one view, the replay tests' data.

    python -m tests.viz.scene_run_data        # about a minute on the shared 2-core machine

It is ``wristmark experiment cube --scene configs/scenes/two_arms.yaml`` (two reference arms
facing each other) cut to its first 0.6 s of cube, with the default controller without its play
probe (configs/controller_encoders.yaml): config.json, result.json, results.md and log_a.csv,
log_b.csv (open loop then closed loop, about 70 cycles per arm), about 130 kB in all.
"""

from __future__ import annotations

import sys
from pathlib import Path

from wristmark.cli.main import main as wristmark

ROOT = Path(__file__).resolve().parents[2]
SCENE_RUN = ROOT / "tests" / "data" / "scene_run"
ARGS = ["experiment", "cube", "--scene", "configs/scenes/two_arms.yaml", "--controller-config",
        "configs/controller_encoders.yaml", "--duration", "0.6", "--no-progress"]


def main() -> int:
    """Run the experiment into tests/data/scene_run (replacing it); the experiment's exit code.
    The recorded paths are made relative to the repository (no file names a path outside it)."""
    import os

    os.chdir(ROOT)
    code = wristmark([*ARGS, "--out", str(SCENE_RUN.relative_to(ROOT)), "--force"])
    for name in ("config.json", "result.json"):
        f = SCENE_RUN / name
        f.write_text(f.read_text().replace(f"{ROOT}/", ""))
    return code


if __name__ == "__main__":
    sys.exit(main())
