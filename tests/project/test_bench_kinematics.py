"""bench/kinematics.py runs and prints the JSON it promises (tiny run)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_prints_json() -> None:
    r = subprocess.run(
        [
            sys.executable,
            str(ROOT / "bench" / "kinematics.py"),
            "--calls",
            "60",
            "--repeats",
            "2",
            "--links",
            "1",
            "3",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("fk_us", "jacobian_us", "fk_plus_jacobian_us"):
        assert out["closed_form"][key] > 0
        assert out["pinocchio"]["3"][key] > 0
    assert out["pinocchio"]["3"]["nq"] == 4 * 3 + 8
    assert isinstance(out["controller_path_under_aim"], bool)
