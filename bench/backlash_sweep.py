"""Closed-loop cube maxima against the size of the arm's dead bands, without and with the
dead-band inversion (the controller file's backlash_method: solvers/play_observer.py
or solvers/backlash_compensation.py).

configs/plant_unseen.yaml with every backlash entry scaled by each factor (0 = no play, 3 = three
times that arm's); the qp controller (or --controllers) at a 60 ms cycle, its settings from
--controller-config (default the shipped configs/controller.yaml), run with its
``backlash_compensation`` off and on. Prints one JSON document (rows: factor, compensation, the
median over --seeds of the closed-loop mean / max and corner overshoot [mm], and each seed's
max) and lists the factors at which the median max stays at or below --limit.

    .venv/bin/python bench/backlash_sweep.py [--factors 0 0.5 1 1.5 2 2.5 3] [--sensor truth-noise] \
        [--seeds 0 1 2] [--controller-config FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from cube_matrix import cube_setup, summary  # noqa: E402  (the script folder bench/ is on sys.path)

from wristmark.cli.option_types import nonnegative_float, positive_float, seed_int  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.sim.experiments import run_cube  # noqa: E402
from wristmark.sim.plant_params import PlantParams  # noqa: E402
from wristmark.sim.setup import default_config  # noqa: E402
from wristmark.solvers.controller import ControllerConfig  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant", default=str(default_config("plant_unseen.yaml")))
    ap.add_argument("--factors", nargs="+", type=nonnegative_float(10.0), default=[0, 0.5, 1, 1.5, 2, 2.5, 3])
    ap.add_argument("--controllers", nargs="+", default=["qp"])
    ap.add_argument("--sensor", choices=("vision", "truth-noise"), default="truth-noise")
    ap.add_argument("--duration", type=positive_float(), help="cut the cube walk to S seconds")
    ap.add_argument("--seeds", nargs="+", type=seed_int(), default=[0])
    ap.add_argument("--controller-config", default=str(default_config("controller.yaml")),
                    help="controller settings (compensation turned off and on)")
    ap.add_argument("--limit", type=positive_float(), default=1.0, help="max error that counts as good [mm]")
    args = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    base = PlantParams.load(args.plant)
    ctrl = ControllerConfig.load(args.controller_config)
    rows = []
    for kind in args.controllers:
        for f in args.factors:
            plant = dataclasses.replace(base, backlash=tuple(f * b for b in base.backlash))
            for comp in (False, True):
                setup = cube_setup(kind, 0.060, args.sensor, comp, plant=plant)
                setup = setup.with_changes(controller=dataclasses.replace(
                    ctrl, kind=kind, dt=0.060, backlash_compensation=comp))
                runs = []
                for seed in args.seeds:
                    with tempfile.TemporaryDirectory() as tmp:
                        runs.append(summary(run_cube(setup, Path(tmp), progress=False, seed=seed,
                                                     duration=args.duration)))
                med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]
                       if k != "stopped" and runs[0][k] is not None}  # orientation: None when position only
                row = {"controller": kind, "factor": f, "backlash": list(plant.backlash), "compensation": comp,
                       **med, "max_mm_per_seed": [r["max_mm"] for r in runs],
                       "stopped": [r["stopped"] for r in runs if r["stopped"]]}
                rows.append(row)
                print(f"{kind} x{f:g} compensation {'on' if comp else 'off'}: mean {row['mean_mm']:.2f} "
                      f"max {row['max_mm']:.2f} overshoot {row['corner_overshoot_max_mm']:.2f} mm",
                      file=sys.stderr, flush=True)
    below = {f"{kind}, compensation {'on' if comp else 'off'}":
             [r["factor"] for r in rows if r["controller"] == kind and r["compensation"] == comp
              and r["max_mm"] <= args.limit]
             for kind in args.controllers for comp in (False, True)}
    print(json.dumps({"plant": args.plant, "controller_config": args.controller_config, "sensor": args.sensor,
                      "seeds": args.seeds, "duration_s": args.duration,
                      "limit_mm": args.limit, "factors_below_limit": below, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
