"""Register the stereo endoscope to the robot (find world_T_left, the pose of {ll} in {w}) on the
simulated bench, through the public API.

The bench's plant file ``plant_misplaced_camera.yaml`` puts the true endoscope 5.8 mm / 3.2 deg
away from where the calibration says. The arm visits a few configurations (each from both
sides), the marker is tracked in {ll} at each, and ``solve_registration`` fits world_T_left
(with the arm's bend gains, stem coupling and backlash). On hardware the same ``collect`` runs
with ``wristmark.rig`` 's serial link and a camera instead (``wristmark register --serial``).

Run: ``python examples/register.py [--fast]`` (``--fast``: 6 poses at 0.3 x 1080p; else 12 at 0.5 x).
Prints one JSON line: the error of the calibration's world_T_left and of the registered one.
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np

from wristmark import MarkerTracker, warm_up
from wristmark.models import default_config
from wristmark.rig import choose_poses, collect, registration_inputs
from wristmark.sim import SimRegistrationRig, load_setup
from wristmark.solvers import solve_registration, transform_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="CI mode: 6 poses, small images")
    args = parser.parse_args()
    n_poses, scale = (6, 0.3) if args.fast else (12, 0.5)

    warm_up()  # one OpenCV thread, the tracker's numba kernels loaded (nothing else changes process state)
    setup = load_setup(plant=default_config("plant_misplaced_camera.yaml"))
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, image_scale=scale))
    camera = setup.tracking_camera  # what the host believes (the calibration), at the image scale
    poses = choose_poses(setup.params, n_poses, camera, setup.marker, seed=0)
    observations = collect(SimRegistrationRig(setup, seed=0), MarkerTracker(camera, setup.marker), setup.params,
                           poses, camera.T_world_left, progress=False)
    result = solve_registration(setup.params, registration_inputs(setup.params, observations))

    truth = np.asarray(setup.true_camera.T_world_left, float)  # only the simulated bench knows it
    before_m, before_rad = transform_error(truth, np.asarray(camera.T_world_left, float))
    after_m, after_rad = transform_error(truth, result.world_T_left)
    print(json.dumps({
        "poses": n_poses, "tracked_visits": sum(o.ok for o in observations), "visits": len(observations),
        "rms_mm": 1000 * result.rms_m,
        "calibration_error": {"translation_mm": 1000 * before_m, "rotation_deg": float(np.degrees(before_rad))},
        "registered_error": {"translation_mm": 1000 * after_m, "rotation_deg": float(np.degrees(after_rad))},
        "world_T_left": result.world_T_left.tolist(),
    }))


if __name__ == "__main__":
    main()
