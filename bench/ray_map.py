"""Benchmark: the renderer's undistorted pixel grid (sim/render/pixel_grid.py) against OpenCV's
``cv2.undistortPoints`` on the same grid, per camera of the shipped calibration and image scale.

Prints JSON: per scale the grid's size, the median time of each over ``--repeat`` runs
(interleaved, so both see the same load), their ratio, and whether the two grids are equal bit
for bit; the ``uptime`` load before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from wristmark.cvs.camera import Camera, scaled_stereo_camera
from wristmark.sim.render.pixel_grid import undistorted_grid
from wristmark.sim.setup import load_setup


def opencv_grid(camera: Camera, w: int, h: int) -> np.ndarray:
    """What RayMap built before: the grid's pixel list through ``Camera.undistort``."""
    u, v = np.meshgrid(np.arange(-1.0, w - 1.0), np.arange(-1.0, h - 1.0))
    return camera.undistort(np.column_stack([u.ravel(), v.ravel()])).reshape(h, w, 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scales", default="1.0,0.5", help="image scales, comma-separated")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    base = load_setup().true_camera
    rows = []
    for scale in (float(s) for s in args.scales.split(",")):
        cam = scaled_stereo_camera(base, scale).left
        w, h = scaled_stereo_camera(base, scale).image_size
        w, h = w + 2, h + 2  # the 1 px border (whole tiles aside)
        undistorted_grid(cam, -1.0, -1.0, 4, 4)  # compiled or loaded before timing
        t_cv, t_kernel = [], []
        equal = True
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            ref = opencv_grid(cam, w, h)
            t_cv.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            grid = undistorted_grid(cam, -1.0, -1.0, w, h)
            t_kernel.append(time.perf_counter() - t0)
            equal &= bool(np.array_equal(ref, grid))
        cv_s, k_s = float(np.median(t_cv)), float(np.median(t_kernel))
        rows.append({"scale": scale, "grid": [w, h], "opencv_s": round(cv_s, 4), "kernel_s": round(k_s, 4),
                     "ratio": round(k_s / cv_s, 3), "bit_equal": equal})
    print(json.dumps({"load_before": load0, "load_after": os.getloadavg()[0], "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
