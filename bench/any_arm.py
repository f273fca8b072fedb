"""Benchmark: every shipped arm (configs/robots/*.yaml) on the simulated bench with vision in the
loop: FK + 6 x n tip Jacobian time, and the cube (wristmark experiment cube, 60 ms cycle, its
<arm>_plant.yaml, or configs/plant.yaml for the paper arm) open and closed loop mean / max.

Targets (issue #28): closed loop mean <= 0.3 mm, max <= 1.0 mm, closed/open <= 10 %.
Prints one JSON object (and a Markdown table on stderr). Usage:
    .venv/bin/python bench/any_arm.py [--duration S] [--arms tendon3 planar ...] [--calls 2000]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian
from wristmark.models.arm_spec import ArmSpec, load_arm, shipped_robot_files
from wristmark.sim.experiments import run_cube
from wristmark.sim.setup import load_setup

TARGET = {"closed_mean_mm": 0.3, "closed_max_mm": 1.0, "ratio": 0.10}


def fk_jacobian_us(spec: ArmSpec, calls: int) -> float:
    """Median over 5 repeats of the mean time [us] of arm_frames + arm_tip_jacobian at one psi."""
    lo, hi = spec.bounds()
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    psis = np.random.default_rng(0).uniform(lo, hi, (calls, spec.n))
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        for q in psis:
            arm_tip_jacobian(spec, q, arm_frames(spec, q))
        times.append((time.perf_counter() - t0) / calls)
    return float(np.median(times) * 1e6)


def cube(robot: Path, duration: float | None) -> dict[str, object]:
    """The cube of one arm: open / closed mean and max [mm], closed/open, wall time [s]."""
    setup = load_setup(robot=robot)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        res = run_cube(setup, Path(out), progress=False, duration=duration)
    o, c = res["open_loop"], res["closed_loop"]
    row = {"open_mean_mm": o["mean_mm"], "open_max_mm": o["max_mm"], "closed_mean_mm": c["mean_mm"],
           "closed_max_mm": c["max_mm"], "ratio": res["ratio"], "stopped": c.get("stopped"),
           "plant": setup.sources.get("plant"), "wall_s": time.perf_counter() - t0}
    row["meets_targets"] = bool(not row["stopped"] and c["mean_mm"] <= TARGET["closed_mean_mm"]
                                and c["max_mm"] <= TARGET["closed_max_mm"] and res["ratio"] <= TARGET["ratio"])
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration", type=float, default=None, help="cut each cube walk to S seconds (default: all)")
    ap.add_argument("--arms", nargs="*", default=None, help="arm file stems (default: every shipped arm)")
    ap.add_argument("--calls", type=int, default=2000, help="configurations per FK + J timing repeat")
    args = ap.parse_args()
    files = [p for p in shipped_robot_files() if args.arms is None or p.stem in args.arms]
    rows: dict[str, dict[str, object]] = {}
    for p in files:
        spec = load_arm(p)
        rows[p.stem] = {"n": spec.n, "m": spec.m, "segments": len(spec.segments),
                        "fk_plus_jacobian_us": fk_jacobian_us(spec, args.calls), **cube(p, args.duration)}
        print(f"{p.stem}: {rows[p.stem]}", file=sys.stderr, flush=True)
    print(json.dumps({"duration_s": args.duration, "targets": TARGET, "arms": rows}, indent=1))
    print("\n| arm | n | m | FK+J [us] | open mean/max [mm] | closed mean/max [mm] | closed/open | targets |",
          file=sys.stderr)
    print("|---|---|---|---|---|---|---|---|", file=sys.stderr)
    for k, r in rows.items():
        print(f"| {k} | {r['n']} | {r['m']} | {r['fk_plus_jacobian_us']:.1f} | {r['open_mean_mm']:.3f} / "
              f"{r['open_max_mm']:.3f} | {r['closed_mean_mm']:.3f} / {r['closed_max_mm']:.3f} | "
              f"{100 * float(r['ratio']):.1f} % | {'met' if r['meets_targets'] else 'not met'} |", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
