"""bench/pbr_tracking.py refuses a bad ``--baseline`` in one line before it renders anything (the
path tracer, an optional extra, is not needed for that)."""

from __future__ import annotations

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
