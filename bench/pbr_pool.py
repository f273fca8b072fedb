"""Path-traced sets pooled: the reports of ``bench/pbr_tracking.py`` taken together, per set and in all.

Usage: python bench/pbr_pool.py REPORT.json [REPORT.json ...] [--wrong-mm MM] [--tracker default|today]
Each REPORT is the JSON that ``bench/pbr_tracking.py`` printed for one set (a seed, its cache).
Prints JSON: for each set and for all the pairs together, the tracked count and rate, wrong
(tip more than ``--wrong-mm`` off), the tip error mean and largest [mm], the coded sleeve's
roll-known count and rate and its rotation error mean [deg], the pairs lost (``SEED/PAIR``
with the reason) and, for the default tracker, its used corners at the truth by the search that
kept them (``corner_errors``: :func:`corner_summary`; reports of 7 December 2026 on). The
targets of issue #33 are stated per set of at least 60 pairs; pooling the sets is the same
measurement on more pairs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np


def corner_summary(corners: list[dict[str, Any]]) -> dict[str, Any]:
    """Corners at the truth (bench/pbr_tracking.py's rows: search, near_clipped, error_px (x, y),
    solve_sigma_px), per search and clipped or not: how many, the RMS error per coordinate [px],
    the median, 90th percentile and largest distance [px], and the solve's median noise [px]."""
    out: dict[str, Any] = {}
    for search, near in sorted({(c["search"], c["near_clipped"]) for c in corners}):
        sel = [c for c in corners if (c["search"], c["near_clipped"]) == (search, near)]
        e = np.array([c["error_px"] for c in sel], float)
        d = np.hypot(e[:, 0], e[:, 1])
        out[f"{search}, {'near' if near else 'not near'} clipped"] = {
            "corners": len(sel), "rms_px": float(np.sqrt(np.mean(e**2))), "median_px": float(np.median(d)),
            "p90_px": float(np.percentile(d, 90)), "max_px": float(d.max()),
            "solve_sigma_median_px": float(np.nanmedian([c["solve_sigma_px"] for c in sel]))}
    return out


def _summary(rows: list[dict[str, Any]], tracker: str, wrong_mm: float) -> dict[str, Any]:
    """One set's (or all sets') numbers for ``tracker`` ('default' or 'today')."""
    ok = [r for r in rows if r[tracker]["ok"]]
    tips = [r[tracker]["tip_mm"] for r in ok]
    coded = [r for r in rows if r["sleeve"] == "coded"]
    known = [r for r in coded if r[tracker]["ok"] and r[tracker]["roll_known"]]
    return {
        "pairs": len(rows),
        "tracked": len(ok),
        "tracked_rate": len(ok) / max(len(rows), 1),
        "wrong": sum(t > wrong_mm for t in tips),
        "tip_error_mean_mm": float(np.mean(tips)) if tips else None,
        "tip_error_max_mm": float(np.max(tips)) if tips else None,
        "coded_roll_known": len(known),
        "coded_roll_known_rate": len(known) / max(len(coded), 1),
        "coded_rotation_mean_deg": float(np.mean([r[tracker]["rot_deg"] for r in known])) if known else None,
        "lost": [f"{r['seed']}/{r['pair']}: {r[tracker]['reason']}" for r in rows if not r[tracker]["ok"]],
        "corner_errors": corner_summary([c for r in ok for c in r[tracker].get("corners", [])]),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("reports", nargs="+", metavar="REPORT.json")
    ap.add_argument("--wrong-mm", type=float, default=0.5)
    ap.add_argument("--tracker", choices=("default", "today"), default="default",
                    help="the default tracker (as shipped) or the report's baseline ('today')")
    a = ap.parse_args()
    sets: dict[str, list[dict[str, Any]]] = {}
    for name in a.reports:
        try:
            report = json.loads(Path(name).read_text())
            rows = [dict(r, seed=report["seed"]) for r in report["rows"]]
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(f"pbr_pool.py: {name}: not a report of bench/pbr_tracking.py ({e})", file=sys.stderr)
            return 2
        sets.setdefault(str(report["seed"]), []).extend(rows)
    out = {"tracker": a.tracker, "wrong_mm": a.wrong_mm,
           "sets": {seed: _summary(rows, a.tracker, a.wrong_mm) for seed, rows in sets.items()},
           "all": _summary([r for rows in sets.values() for r in rows], a.tracker, a.wrong_mm)}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
