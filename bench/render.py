"""Benchmark of the stereo renderer at 1080p: prints JSON with the median time per pair.

Usage: .venv/bin/python bench/render.py [--pairs N] [--noise default] [--scale 1.0] [--arms 1]

``--arms 2`` (or 3) draws several arms in every pair (StereoRenderer.render_arms): each pair's
arm, and copies of it moved by ARM_SHIFT [m] up / down in the left camera's frame {ll}.

A warm-up pair is timed on its own (it loads the compiled numba kernels from their cache);
the median is over the N pairs that follow. Stages are CPU time per pair summed over both camera
threads: tile culling (plan_arm), ray casting (render_arm), optics of the arm's box
(optics_signal_box; optics_signal is the whole-frame path, used only with motion blur) and
the sensor (sensor_image: noise, quantisation, JPEG).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

import wristmark.sim.render.stereo_renderer as render_module
from wristmark.cli.render import PSI_SPREAD
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.models.arm_shape import ArmShape, arm_shape, transformed
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.visibility import random_visible_psi

STAGES = ("plan_arm", "render_arm", "optics_signal_box", "optics_signal", "sensor_image")
ARM_SHIFT = 0.018  # [m] between the arms of a scene, along y of {ll}


def scene(shape: ArmShape, arms: int, T_world_left: np.ndarray) -> list[ArmShape]:
    """The arm and arms - 1 copies moved by +-ARM_SHIFT, +-2 ARM_SHIFT, ... along y of {ll}."""
    W = np.asarray(T_world_left, float)
    out = [shape]
    for i in range(1, arms):
        T = np.eye(4)
        T[1, 3] = ARM_SHIFT * ((i + 1) // 2) * (1 if i % 2 else -1)
        out.append(transformed(shape, W @ T @ np.linalg.inv(W)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--noise", default="default")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--arms", type=int, default=1, help="arms per pair (several: render_arms)")
    a = ap.parse_args()
    warm_up(jit=False)  # OpenCV threads, explicitly (building a renderer changes nothing)
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    if a.scale != 1.0:
        cam = scaled_stereo_camera(cam, a.scale)
    params, marker = RobotParams(), MarkerModel()
    t0 = time.perf_counter()
    r = StereoRenderer(cam, marker if a.arms == 1 else [marker] * a.arms, noise_preset(a.noise), seed=0)
    init = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    shapes = [arm_shape(params, random_visible_psi(params, cam, marker, rng, PSI_SPREAD)) for _ in range(a.pairs)]
    scenes = [scene(s, a.arms, cam.T_world_left) for s in shapes]

    def render(i: int) -> None:
        if a.arms == 1:
            r.render(shapes[i])
        else:
            r.render_arms(scenes[i])
    stages: dict[str, list[float]] = {k: [] for k in STAGES}
    rays: list[int] = []

    def timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kw: Any) -> Any:
            t = time.perf_counter()
            out = fn(*args, **kw)
            stages[name].append(time.perf_counter() - t)
            if name == "render_arm":
                rays.append(int(out))
            return out

        return wrapper

    t = time.perf_counter()
    render(0)  # warm-up
    first = time.perf_counter() - t
    times = []
    for i in range(a.pairs):
        t = time.perf_counter()
        render(i)
        times.append(time.perf_counter() - t)
    # where the time goes (same shapes again, stage timings of both threads summed)
    originals = {k: getattr(render_module, k) for k in STAGES}
    for k in STAGES:
        setattr(render_module, k, timed(k, originals[k]))
    try:
        for i in range(a.pairs):
            render(i)
    finally:
        for k, fn in originals.items():
            setattr(render_module, k, fn)
    # baseline in the same run: what any full-frame 1080p float pipeline pays (copy + blur of a pair)
    img = np.random.default_rng(1).random((cam.image_size[1], cam.image_size[0], 3), dtype=np.float32)
    base = []
    for _ in range(max(3, a.pairs)):
        t = time.perf_counter()
        for _cam in range(2):
            cv2.GaussianBlur(img.copy(), (0, 0), 0.8)
        base.append(time.perf_counter() - t)
    med = float(np.median(times))
    print(
        json.dumps(
            {
                "image_size": list(cam.image_size),
                "noise": a.noise,
                "arms": a.arms,
                "pairs": a.pairs,
                "init_s": round(init, 3),
                "first_pair_ms": round(1000 * first, 1),
                "median_ms_per_pair": round(1000 * med, 1),
                "max_ms_per_pair": round(1000 * max(times), 1),
                "stage_ms_per_pair_cpu": {k: round(1000 * sum(v) / a.pairs, 1) for k, v in stages.items()},
                "rays_per_pair": int(sum(rays) / a.pairs),
                "baseline_copy_blur_pair_ms": round(1000 * float(np.median(base)), 1),
                "ratio_to_baseline": round(med / float(np.median(base)), 2),
                "target_ms": 150,
            }
        )
    )


if __name__ == "__main__":
    main()
