"""The done-when cube's closed loop alone (coded marker, orientation held), one JSON line per run:
closed-loop mean / max of the optical tracker's error [mm], the noise-free max and where the
largest errors are (walk time [s]). The same closed loop as `wristmark experiment cube --marker
configs/marker_coded.yaml --orientation hold --plant P --seed S [--sensor ...]` (its open loop is
skipped: half the time with vision); used for docs/notes/motor-lag-burst.md.

    .venv/bin/python bench/closed_cube.py CONTROLLER.yaml|- truth-noise|vision PLANT.yaml:SEED ...
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time

import numpy as np

from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.rig.loop.metrics import error_stats, tracking_errors
from wristmark.rig.recording.run_log import RunLog
from wristmark.rig.targets.orientation_path import start_configuration
from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, cube_trajectory, workspace_centre
from wristmark.sim.experiments import check_orientation
from wristmark.sim.setup import load_setup, make_direct_loop


def main() -> int:
    ctrl, sensor, *jobs = sys.argv[1:]
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    for job in jobs:
        plant, seed_text = job.rsplit(":", 1)
        seed = int(seed_text)
        t0 = time.time()
        setup = load_setup(marker="configs/marker_coded.yaml", plant=plant, controller=None if ctrl == "-" else ctrl)
        setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor=sensor, seed=seed))
        traj = cube_trajectory(workspace_centre(setup.params), CUBE_SIZE, CUBE_SPEED)
        traj = traj.with_orientation(check_orientation(setup, "hold"), setup.params)
        loop = make_direct_loop(setup, start_configuration(setup.params, traj.sample(0.0)[0]), closed_loop=True,
                                seed=seed)
        log = RunLog()
        loop.run(traj, "closed_loop", True, log, settle=setup.rig.settle_time, progress=False)
        recs = log.phase("closed_loop")
        e = np.asarray(tracking_errors(recs, "p_trk"))
        s = error_stats(e)
        mm = 1000.0 * e
        top = np.argsort(-mm)[:3]
        print(json.dumps({"plant": plant, "seed": seed, "mean": round(s.mean_mm, 4), "max": round(s.max_mm, 4),
                          "true_max": round(1000.0 * float(np.max(tracking_errors(recs, "p_true"))), 4),
                          "top": [(round(float(recs[i].t - recs[0].t), 2), round(float(mm[i]), 3)) for i in top],
                          "wall": round(time.time() - t0, 1)}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
