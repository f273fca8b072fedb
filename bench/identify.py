"""Identification on arms the fit never saw: the shipped unseen plant and held-out plants drawn
for validation (bench/heldout_plants.py with a new seed into a new folder).

Per plant: ``identify`` on the simulated bench (vision in the loop, the reference sleeve), the
parameter errors of the fit against the plant file's truth, the open-loop cube error with the
nominal model and with the identified one (target: mean <= 50 % of the nominal's), the
closed-loop cube with the identified model (vision in the loop; target: max <= 1.0 mm and mean
<= 0.25 mm) and the excitation's cost (seconds of arm motion), and for comparison the closed loop
with the nominal model. Prints one JSON document and a markdown table.

``--robot R`` identifies another arm (a format-2 robot file; give its plant files). ``--source
servo-run`` fits, instead of identify's excitation, the record of a closed-loop cube with the
nominal model (what ``wristmark identify --from-log RUN`` reads: the run's log.csv, written and read
back), as a lab would from a run it already has.

    .venv/bin/python bench/identify.py [--robot R.yaml] [--plants P.yaml ...] [--poses 24]
        [--source excitation|servo-run] [--duration S] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.option_types import int_in, positive_float  # noqa: E402
from wristmark.models.config_files import CONFIG_DIR  # noqa: E402
from wristmark.models.plant_params import PlantParams  # noqa: E402
from wristmark.rig.recording.run_excitation import excitation_from_run  # noqa: E402
from wristmark.rig.recording.run_log import RunLog  # noqa: E402
from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, cube_trajectory, workspace_centre  # noqa: E402
from wristmark.sim.identify_bench import bench_plan, excite_on_bench  # noqa: E402
from wristmark.sim.setup import SimSetup, load_setup  # noqa: E402
from wristmark.sim.trajectory_run import walk_trajectory  # noqa: E402
from wristmark.solvers.identification import identify  # noqa: E402

TARGET_OPEN_RATIO = 0.5
TARGET_CLOSED_MAX_MM = 1.0
TARGET_CLOSED_MEAN_MM = 0.25


def parameter_errors(fit: PlantParams, truth: PlantParams) -> dict[str, Any]:
    """|fit - truth| per key (gains [-], offsets [rad], coupling [-], plays [rad, m...], lag [s];
    the load as the bend it gives: F / k per segment [rad/m], the stiffness being unseparable)."""
    k_fit, k_true = np.asarray(fit.segment_stiffness), np.asarray(truth.segment_stiffness)
    F_fit, F_true = np.asarray(fit.tip_force), np.asarray(truth.tip_force)
    return {
        "bend_gain": np.abs(np.subtract(fit.bend_gain, truth.bend_gain)).tolist(),
        "plane_offset": np.abs(np.subtract(fit.plane_offset, truth.plane_offset)).tolist(),
        "stem_coupling": abs(fit.stem_coupling - truth.stem_coupling),
        "backlash": np.abs(np.subtract(fit.backlash, truth.backlash)).tolist(),
        "actuator_tau": abs(fit.actuator_tau - truth.actuator_tau),
        "load_bend_per_segment": [float(np.linalg.norm(F_fit / kf - F_true / kt)) for kf, kt in zip(k_fit, k_true)],
    }


def cube(setup: SimSetup, closed: bool, duration: float | None, log: RunLog | None = None) -> dict[str, float]:
    """One phase of the cube (open loop: no vision; closed: vision in the loop): tracker errors [mm]."""
    traj = cube_trajectory(workspace_centre(setup.params), CUBE_SIZE, CUBE_SPEED)
    if duration is not None:
        traj = traj.truncated(duration)
    run = walk_trajectory(setup, traj, closed, log if log is not None else RunLog.for_arm(setup.params))
    return {"mean_mm": run.errors.mean_mm, "max_mm": run.errors.max_mm, "stopped": run.stopped}


def servo_run_excitation(setup: SimSetup, duration: float | None) -> tuple[Any, dict[str, float]]:
    """The nominal closed-loop cube's record, written as a run's log.csv and read back as
    ``identify --from-log RUN`` reads it; and the run's errors."""
    log = RunLog.for_arm(setup.params)
    closed = cube(setup, True, duration, log)
    with tempfile.TemporaryDirectory() as tmp:
        log.write_csv(Path(tmp) / "log.csv")
        return excitation_from_run(tmp, setup.params), closed


def one(robot: Path | None, plant_path: Path, poses: int, duration: float | None, source: str) -> dict[str, Any]:
    setup = load_setup(robot=robot, plant=plant_path)
    truth = setup.plant
    t0 = time.perf_counter()
    nominal_closed = None
    if source == "servo-run":
        data, nominal_closed = servo_run_excitation(setup, duration)
    else:
        data = excite_on_bench(setup, bench_plan(setup, poses))
    t1 = time.perf_counter()
    ident = identify(setup.params, data, setup.controller.play_max_for(setup.params))
    t_fit = time.perf_counter() - t0
    t_solve = time.perf_counter() - t1
    modelled = setup.with_changes(model=ident.plant)
    nominal_open = cube(setup, False, duration)
    nominal_closed = nominal_closed or cube(setup, True, duration)
    model_open = cube(modelled, False, duration)
    model_closed = cube(modelled, True, duration)
    ratio = model_open["mean_mm"] / nominal_open["mean_mm"]
    return {
        "robot": str(robot) if robot else "reference", "source": source,
        "plant": str(plant_path), "excitation_s": float(data.meta.get("motion_s", data.times[-1] - data.times[0])),
        "poses": ident.poses, "fit_rms_mm": 1000 * ident.rms_m, "identify_wall_s": t_fit, "fit_wall_s": t_solve,
        "parameter_errors": parameter_errors(ident.plant, truth),
        "open_loop_nominal": nominal_open, "open_loop_model": model_open, "open_ratio": ratio,
        "closed_loop_nominal": nominal_closed, "closed_loop_model": model_closed,
        "targets_met": {"open_ratio": ratio <= TARGET_OPEN_RATIO,
                        "closed_max": model_closed["max_mm"] <= TARGET_CLOSED_MAX_MM,
                        "closed_mean": model_closed["mean_mm"] <= TARGET_CLOSED_MEAN_MM},
    }


def table(rows: list[dict[str, Any]]) -> str:
    lines = ["| plant | excitation [s] | fit rms [mm] | gain err max | offset err max [mrad] | open nominal mean/max "
             "[mm] | open model mean/max [mm] | ratio | closed nominal mean/max [mm] | closed model mean/max [mm] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        pe, on, om, cm = r["parameter_errors"], r["open_loop_nominal"], r["open_loop_model"], r["closed_loop_model"]
        cn = r["closed_loop_nominal"]
        offset = max(pe["plane_offset"]) if pe["plane_offset"] else math.nan
        lines.append(f"| {Path(r['plant']).name} | {r['excitation_s']:.1f} | {r['fit_rms_mm']:.3f} | "
                     f"{max(pe['bend_gain']):.4f} | {1000 * offset:.2f} | "
                     f"{on['mean_mm']:.2f} / {on['max_mm']:.2f} | {om['mean_mm']:.2f} / {om['max_mm']:.2f} | "
                     f"{100 * r['open_ratio']:.1f} % | {cn['mean_mm']:.3f} / {cn['max_mm']:.3f} | "
                     f"{cm['mean_mm']:.3f} / {cm['max_mm']:.3f} |")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", type=Path, help="robot file (default the reference arm)")
    ap.add_argument("--plants", nargs="+", type=Path, default=[CONFIG_DIR / "plant_unseen.yaml"])
    ap.add_argument("--source", choices=("excitation", "servo-run"), default="excitation",
                    help="fit identify's excitation, or a nominal closed-loop cube's record")
    ap.add_argument("--poses", type=int_in(8, 500), default=24)
    ap.add_argument("--duration", type=positive_float(600.0), help="cut the cube to S seconds (quick checks)")
    ap.add_argument("--json", type=Path, help="write the result here too")
    args = ap.parse_args()
    rows = []
    for p in args.plants:
        rows.append(one(args.robot, p, args.poses, args.duration, args.source))
        print(json.dumps(rows[-1]), flush=True)
    out = {"rows": rows, "all_targets_met": all(all(r["targets_met"].values()) for r in rows),
           "worst_closed_max_mm": max(r["closed_loop_model"]["max_mm"] for r in rows),
           "worst_open_ratio": max(r["open_ratio"] for r in rows),
           "median_excitation_s": float(np.median([r["excitation_s"] for r in rows]))}
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1, default=lambda x: None if isinstance(x, float) and
                                        math.isnan(x) else x))
    print(table(rows))
    print(json.dumps({k: v for k, v in out.items() if k != "rows"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
