"""bench/arm_kinematics.py runs and prints the JSON it promises (tiny run; no timing asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_prints_json() -> None:
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "arm_kinematics.py"), "--calls", "40", "--repeats", "2"],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["today_us"] > 0
    assert {"paper.yaml", "tendon3.yaml", "single_tendon.yaml", "planar.yaml"} <= set(out["arms"])
    for arm in out["arms"].values():
        assert arm["fk_plus_jacobian_us"] > 0 and arm["ratio"] > 0 and arm["batch_us_per_config"] > 0
    assert out["arms"]["tendon3.yaml"]["n"] == 7
