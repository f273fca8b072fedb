"""Registration benchmark on the simulated bench: prints JSON.

For configs/plant.yaml and configs/plant_unseen.yaml, each with its tip load and without, the
true camera is moved by CAMERA_OFFSET (in {ll}) and registered from 6, 12 and 24 poses
(rig.registration.poses + sim.registration_bench + solvers.registration, as ``wristmark
register`` does). Per case: the error of world_T_left against the truth (translation [mm],
rotation [deg]) and the same error once the rotation about z_w by segment 1's plane offset o1 is
taken out (o1 is a phi-encoder offset, unobservable by any camera registration: see
docs/calibration.md). Then the closed-loop cube (first ``--duration`` s, ``--image-scale``)
with the 12-pose registration beside the same run with the true transform.

    .venv/bin/python bench/registration.py [--duration 12] [--image-scale 0.5] [--poses 6 12 24]
    .venv/bin/python bench/registration.py --ablation   # one model error at a time, rigid vs estimated

``--ablation``: on the ideal plant plus one of configs/plant.yaml's errors at a time (12 poses),
the registration error when the arm is trusted as modelled (--rigid-arm) beside the one with
its observable errors estimated.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cvs.tracking.tracker import MarkerTracker  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.models.config_files import CONFIG_DIR
from wristmark.rig.registration.poses import choose_poses  # noqa: E402
from wristmark.rig.registration.run import collect, registration_poses  # noqa: E402
from wristmark.sim.experiments import run_cube  # noqa: E402
from wristmark.sim.registration_bench import SimRegistrationRig  # noqa: E402
from wristmark.sim.setup import SimSetup, load_setup  # noqa: E402
from wristmark.solvers.registration import solve_registration, transform_error  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CAMERA_OFFSET = (0.004, 0.003, -0.003, -0.03, 0.035, 0.03)  # [m, m, m, rad, rad, rad]: 5.8 mm, 3.2 deg


def _errors(truth: np.ndarray, W: np.ndarray, o1: float) -> dict[str, float]:
    t, r = transform_error(truth, W)
    Rz = np.eye(4)
    Rz[:2, :2] = [[np.cos(o1), -np.sin(o1)], [np.sin(o1), np.cos(o1)]]
    t1, r1 = transform_error(Rz @ truth, W)
    return {"translation_mm": 1000 * t, "rotation_deg": float(np.degrees(r)),
            "without_o1": {"translation_mm": 1000 * t1, "rotation_deg": float(np.degrees(r1))}}


def register(setup: SimSetup, n: int, seed: int = 0) -> tuple[np.ndarray, dict[str, Any]]:
    """Register on the simulated bench; the transform and its errors."""
    cam = setup.tracking_camera
    t0 = time.perf_counter()
    poses = choose_poses(setup.params, n, cam, setup.marker, seed=seed)
    obs = collect(SimRegistrationRig(setup, seed=seed), MarkerTracker(cam, setup.marker), setup.params, poses,
                  cam.T_world_left, progress=False)
    res = solve_registration(setup.params, registration_poses(setup.params, obs))
    out = _errors(setup.true_camera.T_world_left, res.world_T_left, setup.plant.plane_offset[0])
    out |= {"tracked_visits": int(sum(o.ok for o in obs)), "visits": len(obs), "rms_mm": 1000 * res.rms_m,
            "outliers": len(res.outliers), "wall_s": time.perf_counter() - t0,
            "arm_estimate": {"bend_gain": list(res.arm.bend_gain), "plane_offset_2": res.arm.plane_offset_2,
                             "stem_coupling": res.arm.stem_coupling}}
    return res.world_T_left, out


def cube(setup: SimSetup, W: np.ndarray, duration: float) -> dict[str, float]:
    """Closed-loop cube error with the host believing world_T_left = W."""
    with tempfile.TemporaryDirectory() as d:
        res = run_cube(setup.with_changes(registration=W), Path(d), progress=False, duration=duration)
    c = res["closed_loop"]
    return {"mean_mm": c["mean_mm"], "max_mm": c["max_mm"], "stopped": c.get("stopped") or ""}


ABLATION = {
    "none (ideal plant)": {},
    "bend gains 0.98 / 0.945, o2 = -0.02 rad": {"bend_gain": (0.98, 0.945), "plane_offset": (0.0, -0.02)},
    "stem coupling 0.038": {"stem_coupling": 0.038},
    "backlash (configs/plant.yaml)": {"backlash": (0.008, 0.0001, 0.00003, 0.00003, 0.00003, 0.00003)},
    "tip load (0, 0, -0.03) N": {"tip_force": (0.0, 0.0, -0.03)},
}


def ablation(image_scale: float) -> list[dict[str, Any]]:
    """Registration error per model error, rigid arm vs arm errors estimated (12 poses)."""
    base = load_setup(plant=CONFIG_DIR / "plant_ideal.yaml")
    rows = []
    for name, change in ABLATION.items():
        pl = dataclasses.replace(base.plant, camera_offset=CAMERA_OFFSET, **change)
        setup = base.with_changes(plant=pl, rig=dataclasses.replace(base.rig, image_scale=image_scale))
        cam = setup.tracking_camera
        poses = choose_poses(setup.params, 12, cam, setup.marker)
        obs = collect(SimRegistrationRig(setup), MarkerTracker(cam, setup.marker), setup.params, poses,
                      cam.T_world_left, progress=False)
        row: dict[str, Any] = {"model_error": name}
        for key, arm in (("rigid_arm", False), ("arm_estimated", True)):
            res = solve_registration(setup.params, registration_poses(setup.params, obs), estimate_arm=arm)
            t, r = transform_error(setup.true_camera.T_world_left, res.world_T_left)
            row[key] = {"translation_mm": 1000 * t, "rotation_deg": float(np.degrees(r)), "rms_mm": 1000 * res.rms_m}
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=12.0, help="cube: first S seconds of the walk")
    ap.add_argument("--image-scale", type=float, default=0.5)
    ap.add_argument("--poses", type=int, nargs="+", default=[6, 12, 24])
    ap.add_argument("--no-cube", action="store_true", help="registration errors only")
    ap.add_argument("--ablation", action="store_true", help="one model error at a time, rigid vs estimated arm")
    a = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    if a.ablation:
        print(json.dumps({"camera_offset": list(CAMERA_OFFSET), "image_scale": a.image_scale, "poses": 12,
                          "rows": ablation(a.image_scale)}, indent=1))
        return 0
    rows = []
    for plant in ("plant.yaml", "plant_unseen.yaml"):
        base = load_setup(plant=CONFIG_DIR / plant)
        for load in (True, False):
            pl = dataclasses.replace(base.plant, camera_offset=CAMERA_OFFSET,
                                     tip_force=base.plant.tip_force if load else (0.0, 0.0, 0.0))
            setup = base.with_changes(plant=pl, rig=dataclasses.replace(base.rig, image_scale=a.image_scale))
            row: dict[str, Any] = {"plant": plant, "tip_force_N": list(pl.tip_force),
                                   "plane_offset_1_rad": pl.plane_offset[0], "registration": {}}
            W12 = None
            for n in a.poses:
                W, err = register(setup, n)
                row["registration"][str(n)] = err
                if n == 12:
                    W12 = W
            if not a.no_cube and W12 is not None:
                truth = np.asarray(setup.true_camera.T_world_left, float)
                row["cube_closed_loop"] = {"registered_12": cube(setup, W12, a.duration),
                                           "true_transform": cube(setup, truth, a.duration),
                                           "duration_s": a.duration}
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    print(json.dumps({"camera_offset": list(CAMERA_OFFSET), "image_scale": a.image_scale, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
