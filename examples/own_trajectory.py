"""Walk your own path on the simulated bench, closed loop with vision in the loop, from Python.

The path is a figure-eight in the x_w-z_w plane (facing the endoscope) around the workspace
centre, sampled every few degrees: any (N, 3) array of points in {w} [m] works the same way
(``Trajectory.from_waypoints``). ``run_trajectory`` walks it on a fresh simulated arm: each
60 ms cycle renders the stereo frames, tracks the wrist marker in them and corrects the
command. The same path open loop (the model's commands alone) shows what the loop buys.

Run: ``python examples/own_trajectory.py [--fast]`` (``--fast``: an 8 x 6 mm figure-eight,
0.3 x 1080p frames; else 16 x 10 mm at 0.5 x). Prints one JSON line: mean / max tip error
[mm] (optical tracker vs desired) closed and open loop.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from wristmark import warm_up
from wristmark.rig import Trajectory, workspace_centre
from wristmark.sim import load_setup, run_trajectory

SPEED = 0.010  # [m/s] along the path (the paper's cube speed)


def figure_eight(centre_world: np.ndarray, width: float, height: float, step_deg: float = 5.0) -> np.ndarray:
    """Points (N, 3) in {w} [m] of a closed figure-eight of ``width`` along x_w and ``height``
    along z_w [m] through ``centre_world``, starting and ending there."""
    theta = np.deg2rad(np.arange(0.0, 360.0 + step_deg / 2, step_deg))
    x = 0.5 * width * np.sin(theta)
    z = 0.5 * height * np.sin(2.0 * theta)
    return centre_world + np.column_stack([x, np.zeros_like(x), z])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="CI mode: a small figure-eight, small images")
    args = parser.parse_args()
    (width, height), scale = ((0.008, 0.006), 0.3) if args.fast else ((0.016, 0.010), 0.5)

    warm_up()  # one OpenCV thread, the tracker's numba kernels loaded (the only call that changes process state)
    setup = load_setup()  # the shipped robot, marker, calibration, controller and simulated true arm
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, image_scale=scale))  # the frames' resolution
    path = Trajectory.from_waypoints(figure_eight(workspace_centre(setup.params), width, height), SPEED)

    t0 = time.perf_counter()
    closed = run_trajectory(setup, path)  # closed loop, the marker tracked in every rendered frame
    wall = time.perf_counter() - t0
    open_loop = run_trajectory(setup, path, closed_loop=False)  # the same path from the model alone
    print(json.dumps({
        "path": {"shape": "figure-eight", "width_mm": 1000 * width, "height_mm": 1000 * height,
                 "waypoints": len(path.waypoints), "duration_s": round(path.duration, 3)},
        "closed_loop": {"mean_mm": closed.errors.mean_mm, "max_mm": closed.errors.max_mm,
                        "cycles": closed.errors.n, "lost": closed.stats.lost, "stopped": closed.stopped,
                        "vision_vs_true_mean_mm": closed.summary["vision_vs_true"]["mean_mm"],
                        "wall_s": round(wall, 1)},
        "open_loop": {"mean_mm": open_loop.errors.mean_mm, "max_mm": open_loop.errors.max_mm,
                      "cycles": open_loop.errors.n},
    }))


if __name__ == "__main__":
    main()
