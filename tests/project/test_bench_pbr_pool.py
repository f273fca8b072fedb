"""bench/pbr_pool.py pools the reports of bench/pbr_tracking.py per set and in all, and refuses a
file that is not one in one line (no path tracer needed: the reports are written here)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _row(pair: int, sleeve: str, ok: bool, tip_mm: float = 0.0, roll_known: bool = False,
         rot_deg: float = 0.0) -> dict:
    out = {"ok": ok, "reason": "" if ok else "too few marker corners", "roll_known": roll_known}
    if ok:
        out.update(tip_mm=tip_mm, rot_deg=rot_deg)
    return {"pair": pair, "sleeve": sleeve, "default": out, "today": dict(out, ok=False, reason="lost")}


def _pool(tmp_path: Path, reports: list[dict], *args: str) -> subprocess.CompletedProcess[str]:
    names = []
    for i, report in enumerate(reports):
        names.append(str(tmp_path / f"r{i}.json"))
        Path(names[-1]).write_text(json.dumps(report))
    return subprocess.run([sys.executable, str(ROOT / "bench" / "pbr_pool.py"), *names, *args],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)


def test_sets_are_summed_per_set_and_in_all(tmp_path: Path) -> None:
    a = {"seed": 1, "rows": [_row(0, "reference", True, 0.04), _row(1, "coded", True, 0.06, True, 0.2),
                             _row(2, "reference", False)]}
    b = {"seed": 2, "rows": [_row(0, "reference", True, 0.7), _row(1, "coded", True, 0.02, False)]}
    r = _pool(tmp_path, [a, b])
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    one, two, every = out["sets"]["1"], out["sets"]["2"], out["all"]
    assert (one["pairs"], one["tracked"], one["wrong"], one["coded_roll_known"]) == (3, 2, 0, 1)
    assert one["lost"] == ["1/2: too few marker corners"]
    assert (two["wrong"], two["coded_roll_known_rate"]) == (1, 0.0)  # 0.7 mm > 0.5
    assert (every["pairs"], every["tracked"], every["wrong"]) == (5, 4, 1)
    assert every["tip_error_mean_mm"] == pytest.approx((0.04 + 0.06 + 0.7 + 0.02) / 4)
    assert every["tip_error_max_mm"] == pytest.approx(0.7) and every["coded_rotation_mean_deg"] == pytest.approx(0.2)
    today = json.loads(_pool(tmp_path, [a, b], "--tracker", "today", "--wrong-mm", "1").stdout)
    assert today["all"]["tracked"] == 0 and len(today["all"]["lost"]) == 5


def test_corners_at_the_truth_are_pooled_by_search_and_clipping(tmp_path: Path) -> None:
    """Each tracked pair's used corners (bench/pbr_tracking.py's rows) pooled per search and
    clipped or not: RMS per coordinate, distances, the solve's noise; a lost pair's none."""
    def corner(search: str, near: bool, ex: float, ey: float) -> dict:
        return {"search": search, "near_clipped": near, "error_px": [ex, ey], "solve_sigma_px": 0.1}
    a = {"seed": 1, "rows": [_row(0, "reference", True, 0.04), _row(1, "coded", False)]}
    a["rows"][0]["default"]["corners"] = [corner("first", False, 0.3, 0.4), corner("first", False, 0.0, 0.0),
                                          corner("reduced", True, 0.6, 0.8)]
    a["rows"][1]["default"]["corners"] = [corner("first", False, 9.0, 9.0)]  # lost: not counted
    b = {"seed": 2, "rows": [_row(0, "reference", True, 0.05)]}
    b["rows"][0]["default"]["corners"] = [corner("first", False, 0.0, 1.0)]
    r = _pool(tmp_path, [a, b])
    assert r.returncode == 0, r.stderr
    every = json.loads(r.stdout)["all"]["corner_errors"]
    assert sorted(every) == ["first, not near clipped", "reduced, near clipped"]
    first = every["first, not near clipped"]
    assert first["corners"] == 3 and first["max_px"] == pytest.approx(1.0)
    assert first["rms_px"] == pytest.approx(((0.09 + 0.16 + 1.0) / 6) ** 0.5)
    assert first["median_px"] == pytest.approx(0.5) and first["solve_sigma_median_px"] == pytest.approx(0.1)
    assert every["reduced, near clipped"]["p90_px"] == pytest.approx(1.0)


def test_a_file_that_is_not_a_report_is_one_line_and_exit_2(tmp_path: Path) -> None:
    r = _pool(tmp_path, [{"seed": 1}])
    assert r.returncode == 2 and "not a report of bench/pbr_tracking.py" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not r.stdout
