"""Markdown summary of the long experiment runs under runs/bench/ (as written by the commands in
docs/results.md): cube tables at 60 ms and 33 ms, the unseen plant, accuracy and load.

    .venv/bin/python bench/results_summary.py [--root runs/bench] > summary.md
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

PAPER = "| paper (Fig. 8), 60 ms | 3.25 | 8.40 | 0.82 | 2.59 | 25.2 % | - | - | - |"
HEAD = ("| run | open mean [mm] | open max [mm] | closed mean [mm] | closed max [mm] | closed/open "
        "| corner overshoot max [mm] | vision vs true mean / max [mm] | lost frames |\n"
        "|---|---|---|---|---|---|---|---|---|")


def _cube_rows(path: Path, controller: str | None = None, note: str = "") -> list[str]:
    rows = []
    for r in json.loads(path.read_text())["runs"]:
        if controller is not None and r["controller"] != controller:
            continue
        o, c = r["open_loop"], r["closed_loop"]
        v = c.get("vision_vs_true", {})
        vis = f"{v['mean_mm']:.3f} / {v['max_mm']:.3f}" if v else "-"
        stop = f" (stopped: {c['stopped']})" if c.get("stopped") else ""
        rows.append(f"| {r['name']}{note}{stop} | {o['mean_mm']:.2f} | {o['max_mm']:.2f} | {c['mean_mm']:.2f} | "
                    f"{c['max_mm']:.2f} | {100 * r['ratio']:.1f} % | {c['corner_overshoot_mm']['max']:.2f} | {vis} "
                    f"| {c.get('lost', 0)} of {c['cycles']} |")
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default="runs/bench")
    ap.add_argument("--paper-rows-from", nargs="*", default=[], metavar="JSON",
                    help="more cube_matrix outputs whose `paper`-controller rows are added (marked *)")
    args = ap.parse_args()
    root = Path(args.root)
    out = ["## Cube trajectory (paper IV.C), vision in the loop", "", HEAD, PAPER]
    for name in ("cube_60ms", "cube_33ms", "cube_unseen"):
        f = root / f"{name}.json"
        if f.is_file() and f.stat().st_size:
            out += _cube_rows(f)
    for extra in args.paper_rows_from:
        out += _cube_rows(Path(extra), controller="paper", note=" *")
    acc = root / "accuracy" / "result.json"
    if acc.is_file():
        a = json.loads(acc.read_text())
        t = a["vs_noise_free_truth"]
        out += ["", "## Tip accuracy (paper IV.B)", "",
                "| | positions tracked | stereo vs tracker mean / max [mm] | stereo vs true tip mean / max [mm] |",
                "|---|---|---|---|",
                f"| paper | 40 | {a['paper']['mean_mm']:.2f} / {a['paper']['max_mm']:.2f} | - |",
                f"| wristmark | {a['tracked']} of {a['positions']} | {a['mean_mm']:.3f} / {a['max_mm']:.3f} | "
                f"{t['mean_mm']:.3f} / {t['max_mm']:.3f} |"]
    load = root / "load" / "results.md"
    if load.is_file():
        info = json.loads((root / "load" / "result.json").read_text())
        what = f"{info.get('controller', '?')}, {1000 * info.get('control_dt_s', float('nan')):.0f} ms"
        dur = info.get("duration_s")
        what += f", {dur:.0f} s of the cube" if dur else ""
        out += ["", f"## Tip load sweep ({what})", ""]
        out += load.read_text().splitlines()[2:]
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
