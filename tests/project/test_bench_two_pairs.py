"""bench/two_pairs.py refuses a bad ``--pairs`` in one line, before it renders anything."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_no_pairs_is_one_line_and_exit_2() -> None:
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "two_pairs.py"), "--pairs", "0"],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].endswith("--pairs must be >= 1")
