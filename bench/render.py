"""Benchmark of the stereo renderer at 1080p: prints JSON with the median time per pair.

Usage: .venv/bin/python bench/render.py [--pairs N] [--noise default] [--scale 1.0]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from cvs.calibration_io import load_calibration
from cvs.camera import scaled_stereo_camera
from cvs.marker import MarkerModel
from cvs.render import StereoRenderer
from cvs.render_settings import noise_preset
from cvs.visibility import random_visible_psi
from models.arm_shape import arm_shape
from models.robot_params import RobotParams
from rig.commands.render import PSI_SPREAD


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--noise", default="default")
    ap.add_argument("--scale", type=float, default=1.0)
    a = ap.parse_args()
    cam = load_calibration(Path(__file__).resolve().parents[1] / "configs" / "camera.yaml")
    if a.scale != 1.0:
        cam = scaled_stereo_camera(cam, a.scale)
    params, marker = RobotParams(), MarkerModel()
    t0 = time.perf_counter()
    r = StereoRenderer(cam, marker, noise_preset(a.noise), seed=0)
    init = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    shapes = [arm_shape(params, random_visible_psi(params, cam, marker, rng, PSI_SPREAD)) for _ in range(a.pairs)]
    times = []
    for s in shapes:
        t = time.perf_counter()
        r.render(s)
        times.append(time.perf_counter() - t)
    print(
        json.dumps(
            {
                "image_size": list(cam.image_size),
                "noise": a.noise,
                "pairs": a.pairs,
                "init_s": round(init, 3),
                "median_ms_per_pair": round(1000 * float(np.median(times)), 1),
                "max_ms_per_pair": round(1000 * max(times), 1),
            }
        )
    )


if __name__ == "__main__":
    main()
