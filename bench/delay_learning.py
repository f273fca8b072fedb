"""Benchmark: the delay compensation's learnt motion map against the model alone, at old frames.

The in-process cube (pty emulator, simulated clock) with frames that show the arm ``frame_age``
before each cycle's start (rig ``frame_age``) and commands ``--command-delay`` after it: the
compensation then moves every measurement on by the model's motion over the frame's age, and
the arm's gain errors leave a bias that grows with the age unless the map learnt from the
measured motion (rig ``delay_compensation_learn_window``, rig/loop/motion_correction.py) corrects
it. For each age, each seed of the rig's noise and the window off (0) and on (the rig file's),
the true-tip error (mean, max) of the cube, and the learnt map at the end.
Prints one JSON object.
Usage: .venv/bin/python bench/delay_learning.py [--ages 0 0.05 0.1] [--seeds 0 1 2] [--scale 1.0]
       [--dt 0.11] [--command-delay 0.048] [--plant configs/plant_unseen.yaml] [--duration 20]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
from typing import Any

import numpy as np

from wristmark.cli import servo as S
from wristmark.cli.option_types import float_in, int_in, positive_float
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.rig.loop.servo_summary import summarize
from wristmark.sim.servo_bench import open_sim_session
from wristmark.sim.setup import load_setup


def run(age: float, window: float, seed: int, a: argparse.Namespace) -> dict[str, Any]:
    """One in-process cube: frames ``age`` s old, the learnt map's window ``window`` s (0: off)."""
    setup = load_setup(plant=a.plant)
    rig = dataclasses.replace(setup.rig, image_scale=a.scale, control_dt=a.dt, vision_latency=a.command_delay,
                              frame_age=age, seed=seed, delay_compensation_learn_window=window)
    setup = setup.with_changes(rig=rig)
    traj = S.build_trajectory(setup, "cube", None, a.duration)
    psi0 = S.start_configuration(setup, traj)
    session = open_sim_session(setup, psi0, S.LinkOptions(kind="emulator"), seed=seed)
    out = S.run_servo(setup, traj, session, psi0, settle=setup.rig.settle_time)
    c = summarize(setup, traj, session, out)["closed_loop"]
    return {"mean_mm": c["noise_free"]["mean_mm"], "max_mm": c["noise_free"]["max_mm"],
            **({"motion_map": c["motion_map"]["matrix"]} if "motion_map" in c else {})}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ages", type=float_in(0.0, 1.0), nargs="+", default=[0.0, 0.05, 0.1], help="frame ages [s]")
    ap.add_argument("--seeds", type=int_in(0, 2**31 - 1), nargs="+", default=[0, 1, 2], help="the rig's noise seeds")
    ap.add_argument("--scale", type=float_in(0.05, 1.0), default=1.0, help="image scale (default 1: 1080p)")
    ap.add_argument("--dt", type=positive_float(1.0), default=0.11,
                    help="control cycle [s] (default 0.11: the virtual lab's camera at 1080p here)")
    ap.add_argument("--command-delay", type=positive_float(1.0), default=0.048,
                    help="command after the cycle's start [s] (default 0.048, the lab's at 1080p)")
    ap.add_argument("--duration", type=positive_float(600.0), default=20.0, help="cube duration [s]")
    ap.add_argument("--plant", metavar="YAML", help="the true arm (default configs/plant.yaml)")
    a = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    window = load_setup().rig.delay_compensation_learn_window
    if window <= 0:
        print("error: the rig file's delay_compensation_learn_window is 0 (nothing to compare)", file=sys.stderr)
        return 2
    rows = []
    for age in a.ages:
        runs = {name: [run(age, w, s, a) for s in a.seeds] for name, w in (("model_only", 0.0), ("learnt", window))}
        means = {name: float(np.mean([r["mean_mm"] for r in rs])) for name, rs in runs.items()}
        rows.append({"frame_age_s": age, "runs": runs, "mean_of_means_mm": means,
                     "ratio_learnt_to_model_only": round(means["learnt"] / means["model_only"], 3)})
    print(json.dumps({"machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
                      "plant": a.plant or "configs/plant.yaml", "image_scale": a.scale, "control_dt_s": a.dt,
                      "command_delay_s": a.command_delay, "learn_window_s": window, "seeds": a.seeds,
                      "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
