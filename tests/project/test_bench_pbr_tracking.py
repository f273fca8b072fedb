"""bench/pbr_tracking.py refuses a bad ``--baseline`` in one line before it renders anything (the
path tracer, an optional extra, is not needed for that); with the path tracer (`make pbr`) it
renders, keeps and tracks pairs, and tracks the kept pairs again the same."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(("item", "message"), [
    ("axis.nope=1", "KEY a TrackerSettings field or GROUP.FIELD"),
    ("axis.arm_offsets=[", "VALUE in JSON"),
    ("axis.arm_offsets=[-1]", "AxisEvidenceSettings.arm_offsets must be > 0"),
])
def test_a_bad_baseline_is_one_line_and_exit_2(item: str, message: str) -> None:
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "pbr_tracking.py"), "--baseline", item],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr.strip().splitlines()[-1]
    assert "Traceback" not in r.stderr


def test_without_the_path_tracer_a_pair_to_render_is_one_line_and_exit_2(tmp_path: Path) -> None:
    # a Mitsuba that cannot be imported, as on a machine without the extra 'pbr'
    (tmp_path / "mitsuba").mkdir()
    (tmp_path / "mitsuba" / "__init__.py").write_text("raise ImportError('not installed here')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT)]))
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "pbr_tracking.py"), "--pairs", "1",
                        "--cache", str(tmp_path / "cache")], capture_output=True, text=True, timeout=120, cwd=ROOT,
                       env=env)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [
        "pbr_tracking: error: --engine pbr needs Mitsuba 3: pip install 'wristmark[pbr]' (scripts/ensure-pbr.sh)"]
    assert not (tmp_path / "cache").exists()  # nothing rendered, nothing kept


def _stripped(report: dict) -> list[dict]:
    """The report's rows without the times (they differ from run to run)."""
    return [{k: ({f: v for f, v in o.items() if f != "ms"} if isinstance(o, dict) else o) for k, o in row.items()}
            for row in report["rows"]]


@pytest.mark.pbr
@pytest.mark.slow
def test_pairs_rendered_and_kept_are_tracked_again_the_same_from_the_cache(tmp_path: Path) -> None:
    cmd = [sys.executable, str(ROOT / "bench" / "pbr_tracking.py"), "--pairs", "2", "--image-scale", "0.5",
           "--spp", "8", "--cache", str(tmp_path / "cache")]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=240, cwd=ROOT)
    assert first.returncode == 0, f"{first.stderr.strip()} (the path tracer: `make pbr`)"
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["pair_0.npz", "pair_1.npz"]
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert again.returncode == 0, again.stderr
    a, b = json.loads(first.stdout), json.loads(again.stdout)
    assert a["pairs"] == 2 and a["image_size"] == [960, 540]
    assert [r["sleeve"] for r in a["rows"]] == ["reference", "coded"]
    assert a["default"]["tracked_rate"] > 0  # half-size pairs: measured 2 of 2 (0.45 and 0.15 mm)
    # the tracked pairs' corners at the truth, by search: the first search's within a pixel
    first = a["default"]["corner_errors"]["first, not near clipped"]
    assert first["corners"] >= 3 and first["rms_px"] < 0.5 and first["max_px"] < 1.5
    # the kept pairs are the rendered ones, bit for bit (NaN, a lost pair's RMS, compared as text)
    assert json.dumps(_stripped(a), sort_keys=True) == json.dumps(_stripped(b), sort_keys=True)
