"""bench/bar_edges.py on a committed path-traced pair: where the bar measurement's largest
gradient, an erf edge fit and the tracker's own fit put the print's edges at the true pose; a
missing pair in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _bench(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(ROOT / "bench" / "bar_edges.py"), *args], capture_output=True,
                          text=True, timeout=300, cwd=ROOT)


def test_on_a_close_blurred_sleeve_the_erf_fit_finds_the_edges_the_gradient_test_refuses() -> None:
    r = _bench("--pbr-data", "coded_close")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["pairs"] == 1 and out["rows"][0]["pair"] == "coded_close"
    pooled = out["pooled"]
    refused, kept = pooled["refused"], pooled["kept"]
    assert pooled["samples"] == refused["gradient"]["n"] + kept["gradient"]["n"] > 40
    # blurred (the fitted sigma ~2 px): the slope test refuses most edges, and where the largest
    # gradient puts them is ~0.5 px off; the erf fit puts them nearer
    assert refused["gradient"]["n"] > 3 * kept["gradient"]["n"] and pooled["erf_sigma_median_px"] > 1.5
    assert refused["erf"]["n"] >= 0.9 * refused["gradient"]["n"]
    assert refused["erf"]["median_abs_px"] < 0.6 * refused["gradient"]["median_abs_px"]
    # the tracker's own fit keeps most of them, within its 2.5 px bound on the blur, and as near
    fit = pooled["tracker_fit"]
    assert fit["sigma <= 2.5"]["n"] >= 0.5 * refused["gradient"]["n"]
    assert fit["sigma <= 2.5"]["rms_px"] < 0.5 * refused["gradient"]["rms_px"]


def test_an_unknown_pair_is_one_line_and_exit_2() -> None:
    r = _bench("--pbr-data", "no_such_pair")
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bar_edges: no committed path-traced pair 'no_such_pair'")
