"""The cube experiment (paper IV.C) for several controllers, cycle times and plants, side by side.

Runs ``sim.experiments.run_cube`` (open loop and closed loop on fresh simulated plants, the
vision pipeline in the loop unless ``--sensor truth-noise``) for every combination asked for,
writes each run folder under ``--out`` and prints one JSON document; a markdown table of all
runs beside the paper's numbers goes to ``OUT/table.md``. ``--compensation off on`` runs each
combination without and with the dead-band inversion (the controller file's
backlash_method: solvers/play_observer.py); the columns give the closed loop's mean / max and
its corner overshoot (max and mean over the corners) per controller. ``--orientations none
hold`` runs each combination without and with the
tip frame's orientation held (qp only: the paper controller is position-only and is skipped
for hold/follow); the orientation columns are the optical tracker's orientation against the
desired one [deg] (open and closed loop; "-" when position only). ``--marker`` picks the sleeve
(configs/marker_coded.yaml for the full orientation; the reference sleeve controls the axis only).

    .venv/bin/python bench/cube_matrix.py --controllers qp paper --dts 0.060 0.033 [--controller-config FILE] \
        [--plants configs/plant.yaml configs/plant_unseen.yaml tests/data/heldout_plants/*.yaml] \
        [--compensation off on] [--orientations none hold] [--marker configs/marker_coded.yaml] \
        [--sensor vision] [--duration S] [--image-scale F]

Long: with vision a full cube takes ~6-12 min of wall time per closed-loop run on 2 cores.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import sys
import time
from pathlib import Path
from typing import Any

from wristmark.cli.option_types import positive_float  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.rig.targets.orientation_path import ORIENTATION_MODES  # noqa: E402
from wristmark.sim.experiments import PAPER_CUBE, run_cube  # noqa: E402
from wristmark.sim.plant_params import PlantParams  # noqa: E402
from wristmark.sim.setup import SimSetup, default_config, load_setup  # noqa: E402

HEADER = ("| run | open mean [mm] | open max [mm] | closed mean [mm] | closed max [mm] | closed/open "
          "| corner overshoot max [mm] | corner overshoot mean [mm] | open orient. mean / max [deg] "
          "| closed orient. mean / max [deg] | wall [s] |")


def cube_setup(kind: str, dt: float, sensor: str, compensation: bool, plant: PlantParams | None = None,
               plant_file: str | None = None, marker_file: str | None = None,
               image_scale: float | None = None, controller_file: str | None = None) -> SimSetup:
    """The default setup with this controller kind, cycle [s], sensor, compensation, plant and
    marker (and images at ``image_scale`` x the calibrated size)."""
    setup = load_setup(plant=plant_file, marker=marker_file, controller=controller_file)
    if image_scale is not None:
        setup = setup.with_changes(rig=dataclasses.replace(setup.rig, image_scale=image_scale))
    rig = dataclasses.replace(setup.rig, control_dt=dt, sensor=sensor,
                              vision_latency=min(setup.rig.vision_latency, 0.75 * dt))
    rig.validate()
    ctrl = dataclasses.replace(setup.controller, kind=kind, dt=dt, backlash_compensation=compensation)
    ctrl.validate()
    return setup.with_changes(rig=rig, controller=ctrl, **({"plant": plant} if plant is not None else {}))


def summary(res: dict[str, Any]) -> dict[str, Any]:
    """The closed loop's numbers of a cube result [mm]."""
    c = res["closed_loop"]
    return {"mean_mm": c["mean_mm"], "max_mm": c["max_mm"], "stopped": c.get("stopped", ""),
            "corner_overshoot_max_mm": c["corner_overshoot_mm"]["max"],
            "corner_overshoot_mean_mm": c["corner_overshoot_mm"]["mean"],
            "orientation_mean_deg": c.get("orientation_mean_deg"), "orientation_max_deg": c.get("orientation_max_deg")}


def _orient(phase: dict) -> str:
    """Orientation mean / max [deg] of a phase, "-" when it was position only."""
    if phase.get("orientation_mean_deg") is None:
        return "-"
    return f"{phase['orientation_mean_deg']:.2f} / {phase['orientation_max_deg']:.2f}"


def _row(name: str, res: dict) -> str:
    o, c = res["open_loop"], res["closed_loop"]
    return (f"| {name} | {o['mean_mm']:.2f} | {o['max_mm']:.2f} | {c['mean_mm']:.2f} | {c['max_mm']:.2f} | "
            f"{100 * res['ratio']:.1f} % | {c['corner_overshoot_mm']['max']:.2f} | "
            f"{c['corner_overshoot_mm']['mean']:.2f} | {_orient(o)} | {_orient(c)} | {res['wall_s']:.0f} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controllers", nargs="+", default=["qp", "paper"])
    ap.add_argument("--dts", nargs="+", type=positive_float(1.0), default=[0.060, 0.033], help="control cycles [s]")
    ap.add_argument("--plants", nargs="+", default=[str(default_config("plant.yaml"))])
    ap.add_argument("--compensation", nargs="+", choices=("off", "on"), default=["off"],
                    help="dead-band inversion off and/or on")
    ap.add_argument("--orientations", nargs="+", choices=ORIENTATION_MODES, default=["none"],
                    help="tip-frame orientation modes to run (hold/follow: qp only)")
    ap.add_argument("--marker", help="marker file (default configs/marker.yaml; configs/marker_coded.yaml: roll known)")
    ap.add_argument("--image-scale", type=positive_float(1.0), help="images at F x the calibrated size")
    ap.add_argument("--sensor", choices=("vision", "truth-noise"), default="vision")
    ap.add_argument("--duration", type=positive_float(), help="cut the cube walk to S seconds")
    ap.add_argument("--out", default="runs/bench/cube_matrix")
    ap.add_argument("--controller-config", help="controller settings (default configs/controller.yaml; "
                    "configs/controller_plain.yaml: no dead-band inversion)")
    args = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    out = Path(args.out)
    results = []
    p: dict[str, Any] = PAPER_CUBE
    lines = [HEADER, "|---|---|---|---|---|---|---|---|---|---|---|",
             f"| paper (Fig. 8), 60 ms | {p['open_loop']['mean_mm']:.2f} | {p['open_loop']['max_mm']:.2f} | "
             f"{p['closed_loop']['mean_mm']:.2f} | {p['closed_loop']['max_mm']:.2f} | "
             f"{100 * p['ratio']:.1f} % | - | - | - | - | - |"]
    for plant, kind, dt, comp, orient in itertools.product(args.plants, args.controllers, args.dts, args.compensation,
                                                           args.orientations):
        if orient != "none" and kind == "paper":
            continue  # the paper controller is position-only
        setup = cube_setup(kind, dt, args.sensor, comp == "on", plant_file=plant, marker_file=args.marker,
                           controller_file=args.controller_config,
                           image_scale=args.image_scale)
        name = f"{Path(plant).stem}, {kind}, {1000 * dt:.0f} ms, compensation {comp}, orientation {orient}"
        t0 = time.perf_counter()
        res = run_cube(setup, out / f"{Path(plant).stem}_{kind}_{1000 * dt:.0f}ms_comp_{comp}_{orient}",
                       progress=False, duration=args.duration, orientation=orient)
        res["wall_s"] = time.perf_counter() - t0
        res["name"] = name
        lines.append(_row(name, res))
        print(lines[-1], file=sys.stderr, flush=True)
        results.append({"compensation": comp == "on", "plant": plant, "orientation": orient, **{
            k: res[k] for k in ("name", "controller", "control_dt_s", "sensor", "open_loop", "closed_loop", "ratio",
                                "wall_s", "run_dir")}})
    out.mkdir(parents=True, exist_ok=True)
    table = f"# Cube trajectory, sensor {args.sensor}\n\n" + "\n".join(lines) + "\n"
    (out / "table.md").write_text(table)
    print(json.dumps({"sensor": args.sensor, "marker": args.marker, "duration_s": args.duration, "runs": results},
                     indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
