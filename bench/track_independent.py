"""Benchmark ``wristmark track`` on stereo sets from the independent renderer (wristmark_testing/independent_render.py).

Renders N pairs (default 20, 1920x1080) into a temporary folder (or ``--keep DIR``), runs
``wristmark track --json`` on them in a subprocess and prints JSON: success rate, tip error mean / max [mm]
(tracker tip vs truth tip, both in the left camera frame), corner error vs truth [px] (tracker corners
matched to the nearest visible true corner), the tracker's median time per pair [ms] and the wall-clock
time per pair of the whole call [s] (includes start-up), plus the failures with their reason strings.

Usage: ``.venv/bin/python bench/track_independent.py [--pairs 20] [--seed 0] [--columns 12]
[--radius 0.00455] [--jpeg Q] [--gray] [--direction right|left|random] [--glare] [--scale 1] [--keep DIR]
[--rows]``
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

from wristmark_testing import independent_dataset_check as check
from wristmark_testing import independent_render as render

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    """Render, track, score; print one JSON object."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--columns", type=int, default=12)
    p.add_argument("--radius", type=float, default=0.00455, help="sleeve radius [m]")
    p.add_argument("--jpeg", type=int, default=None)
    p.add_argument("--gray", action="store_true")
    p.add_argument("--direction", choices=["right", "left", "random"], default="right")
    p.add_argument("--glare", action="store_true", help="stress look: no exposure control, strong sheen")
    p.add_argument("--keep", default=None, help="write the dataset here and keep it")
    p.add_argument("--rows", action="store_true", help="include per-pair rows")
    p.add_argument("--wristmark", default=str(ROOT / ".venv" / "bin" / "wristmark"))
    a = p.parse_args(argv)

    tmp = None
    if a.keep:
        out = Path(a.keep)
        if out.exists():
            shutil.rmtree(out)
    else:
        tmp = tempfile.mkdtemp(prefix="wm_indep_")
        out = Path(tmp) / "ds"
    try:
        t0 = time.perf_counter()
        look = (render.glare_look(a.jpeg, a.gray, a.direction) if a.glare
                else render.Look(jpeg=a.jpeg, gray=a.gray, direction=a.direction))
        info = render.render_dataset(out, a.pairs, a.seed, a.scale, render.Marker(radius=a.radius, columns=a.columns),
                                     look)
        t_render = time.perf_counter() - t0
        results, wall = check.run_track(out, a.wristmark)
        score = check.score_track(out, results)
        if not a.rows:
            score.pop("rows")
        summary = {
            "dataset": str(out) if a.keep else None,
            "renderer": "wristmark_testing/independent_render.py",
            "seed": a.seed,
            "image_size": info["image_size"],
            "columns": a.columns,
            "radius_m": a.radius,
            "jpeg": a.jpeg,
            "gray": a.gray,
            "direction": a.direction,
            "glare": a.glare,
            "render_s_per_pair": t_render / max(a.pairs, 1),
            "track_wall_s_per_pair": wall / max(a.pairs, 1),
            **score,
        }
        print(json.dumps(summary, indent=1))
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
