"""The virtual lab's camera pipeline (render a stereo pair, encode it side by side as one JPEG),
this build against an older one in the same run: CPU time, wall time and identical bytes.

Usage: .venv/bin/python bench/render_1080p.py [--baseline REF] [--pairs N] [--rounds R]
       [--scale 1.0] [--noise default] [--quality 90]

The baseline is the package ``wristmark`` of git revision REF (default: the build before the
renderer of issue 11 (b) was made faster), extracted once under runs/bench-baseline/ (its numba
kernels compile on the first run there). Each round runs both builds in turn, each in a fresh
process rendering the same N arm shapes (a warm-up pair first, not counted); per pair it records
the process's CPU time (time.process_time: every thread, so the machine's other load does not
count), the wall time and SHA-256 of the left image, the right image and the JPEG; then the
same pairs again with each stage's thread CPU time summed (the names of STAGES in sim/render/stereo_renderer.py; the
rest is copies, np.hstack, the JPEG encode and thread hand-offs). Prints JSON: medians per build
over all rounds (``fps_cpu_2_cores``: the rate if the pipeline had both cores to itself), the
ratio this / baseline, and whether every pair's bytes are identical between the builds. The
machine is shared: CPU time is the measure, wall time is noted.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import os
import subprocess
import sys
import tarfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BASELINE = "e8dedf81853666ebe61f22dcb0e4fe510110ba11"  # main before issue 11 (b)'s faster renderer
STAGES = ("plan_arm", "render_arm", "optics_signal_box", "optics_signal", "sensor_image")  # stereo_renderer.py


def _worker(a: argparse.Namespace) -> None:
    """One build, in this process: render and encode the pairs, print one JSON line."""
    import cv2

    from wristmark.cli.render import PSI_SPREAD
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.camera import scaled_stereo_camera
    from wristmark.models.arm_shape import arm_shape
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.models.marker import MarkerModel
    from wristmark.models.robot_params import RobotParams
    from wristmark.sim.render import process as render_process
    from wristmark.sim.render.settings import noise_preset
    from wristmark.sim.render.stereo_renderer import StereoRenderer
    from wristmark.sim.visibility import random_visible_psi

    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    if a.scale != 1.0:
        cam = scaled_stereo_camera(cam, a.scale)
    params, marker = RobotParams(), MarkerModel()
    cv2.setNumThreads(1)  # what wristmark.warm_up(jit=False) does (the baseline build has no warm_up)
    r = StereoRenderer(cam, marker, noise_preset(a.noise), seed=0)
    rng = np.random.default_rng(0)
    shapes = [arm_shape(params, random_visible_psi(params, cam, marker, rng, PSI_SPREAD)) for _ in range(a.pairs + 1)]
    encode = getattr(render_process, "render_pair_jpeg", None)  # this build's pipeline, if it has one

    def one(shape: Any) -> tuple[bytes, bytes, bytes]:
        if encode is not None:
            jpeg, left, right = encode(r, shape, a.quality)
            return jpeg, left.tobytes(), right.tobytes()
        pair = r.render(shape)  # the older builds' render process: render, np.hstack, encode
        ok, buf = cv2.imencode(".jpg", np.hstack([pair.left, pair.right]), [cv2.IMWRITE_JPEG_QUALITY, a.quality])
        assert ok
        return buf.tobytes(), pair.left.tobytes(), pair.right.tobytes()

    one(shapes[0])  # warm-up: loads the kernels
    cpu, wall, digests = [], [], []
    for s in shapes[1:]:
        c0, w0 = time.process_time(), time.perf_counter()
        jpeg, left, right = one(s)
        cpu.append(1e3 * (time.process_time() - c0))
        wall.append(1e3 * (time.perf_counter() - w0))
        digests.append([hashlib.sha256(b).hexdigest()[:16] for b in (left, right, jpeg)])
    # where the CPU goes: the same shapes again, each stage's thread CPU time summed over both threads
    from wristmark.sim.render import stereo_renderer as render_module

    stages: dict[str, float] = {k: 0.0 for k in STAGES}
    originals = {k: getattr(render_module, k) for k in STAGES}

    def timed(name: str, fn: Any) -> Any:
        def wrapper(*args: Any, **kw: Any) -> Any:
            t = time.thread_time()
            try:
                return fn(*args, **kw)
            finally:
                stages[name] += time.thread_time() - t

        return wrapper

    for k in STAGES:
        setattr(render_module, k, timed(k, originals[k]))
    try:
        t_all = time.process_time()
        for s in shapes[1:]:
            one(s)
        t_all = time.process_time() - t_all
    finally:
        for k, fn in originals.items():
            setattr(render_module, k, fn)
    per_pair = {k: 1e3 * v / a.pairs for k, v in stages.items()}
    per_pair["rest (copies, hstack, JPEG encode, threads)"] = 1e3 * t_all / a.pairs - sum(per_pair.values())
    print(json.dumps({"cpu_ms": cpu, "wall_ms": wall, "sha": digests, "stages_ms": per_pair}))


def _baseline_dir(ref: str) -> Path:
    """runs/bench-baseline/SHA holding ``wristmark`` of revision ``ref`` (extracted once)."""
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", ref], check=True, capture_output=True,
                         text=True).stdout.strip()
    out = ROOT / "runs" / "bench-baseline" / sha
    if not (out / "wristmark").is_dir():
        tar = subprocess.run(["git", "-C", str(ROOT), "archive", sha, "wristmark"], check=True,
                             capture_output=True).stdout
        out.mkdir(parents=True, exist_ok=True)
        with tarfile.open(fileobj=io.BytesIO(tar)) as t:
            t.extractall(out, filter="data")
    return out


def _run(a: argparse.Namespace, pythonpath: Path | None) -> dict[str, Any]:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    cmd = [sys.executable, __file__, "--worker", "--pairs", str(a.pairs), "--scale", str(a.scale), "--noise",
           a.noise, "--quality", str(a.quality)]
    cwd = pythonpath if pythonpath is not None else ROOT  # the baseline's package, not this checkout's
    p = subprocess.run(cmd, env=env, cwd=cwd, check=True, capture_output=True, text=True)
    out: dict[str, Any] = json.loads(p.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline", default=BASELINE, help="git revision of the older build")
    ap.add_argument("--pairs", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--noise", default="default")
    ap.add_argument("--quality", type=int, default=90)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        _worker(a)
        return
    base_dir = _baseline_dir(a.baseline)
    runs: dict[str, list[dict[str, Any]]] = {"baseline": [], "this": []}
    for _ in range(a.rounds):
        runs["baseline"].append(_run(a, base_dir))
        runs["this"].append(_run(a, None))
    res: dict[str, Any] = {"baseline_rev": base_dir.name[:12], "scale": a.scale, "noise": a.noise, "quality": a.quality,
                           "pairs": a.pairs, "rounds": a.rounds, "load_1min": round(os.getloadavg()[0], 2)}
    for k, rs in runs.items():
        cpu = [c for r in rs for c in r["cpu_ms"]]
        wall = [w for r in rs for w in r["wall_ms"]]
        res[k] = {"cpu_ms_median": round(float(np.median(cpu)), 1), "wall_ms_median": round(float(np.median(wall)), 1),
                  "fps_cpu_2_cores": round(2000 / float(np.median(cpu)), 1),
                  "stage_cpu_ms_per_pair": {n: round(float(np.median([r["stages_ms"][n] for r in rs])), 1)
                                            for n in rs[0]["stages_ms"]}}
    res["cpu_ratio"] = round(res["this"]["cpu_ms_median"] / res["baseline"]["cpu_ms_median"], 3)
    res["wall_ratio"] = round(res["this"]["wall_ms_median"] / res["baseline"]["wall_ms_median"], 3)
    sha = [r["sha"] for r in runs["baseline"] + runs["this"]]
    res["identical_images"] = all(s == sha[0] for s in sha)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
