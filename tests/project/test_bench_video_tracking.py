"""bench/video_tracking.py runs and prints the JSON it promises (tiny run: 8 small frames)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_bench_prints_json() -> None:
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "video_tracking.py"), "--frames", "8", "--fps", "20",
                        "--scale", "0.5", "--repeat", "1"], capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["video"]["size_px"] == [1920, 540] and out["decode_only"]["grey"]["frames"] == 8
    assert out["tracked_unpaced"]["processed"] == 8 and out["tracked_unpaced"]["found"] >= 6
    paced = out["paced"][0]
    assert paced["processed"] + paced["dropped"] == 8 and paced["tracking_ms"]["median"] > 0
    assert out["target"]["worst_dropped_percent"] == paced["dropped_percent"]
    # each tracker prepared as `wristmark track --source` prepares it; the run's collections and spikes
    assert out["prepared"] is True and set(paced["gc"]["collections"]) == {"0", "1", "2"}
    assert len(paced["spikes"]) == min(paced["frames_over_one_period"], 8)
    assert all(s["ms"] > 1e3 / 20 and "detect" in s["stages_ms"] for s in paced["spikes"])
