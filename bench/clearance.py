"""Benchmark: the clearance between arms (solvers/clearance.py).

Prints JSON: per chord count K (capsules per segment) the distance error against K = 64 (the
capsules cover the tube, so a distance is under-estimated by up to the chords' sagitta: error =
d_64 - d_K >= 0) over random pairs of reference arms, and the cost of body_capsules and
clearance_rows; then the qp controller's ``velocity`` per call (medians): without obstacles,
with obstacles far (no row) and near (rows in the QP).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable

import numpy as np

from wristmark.models.kinematics import tip_position
from wristmark.models.limits import psi_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers.clearance import body_capsules, clearance_rows, min_distance, transformed
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller


def _median_us(fn: Callable[[], object], n: int = 2000) -> float:
    ts = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t0
    return float(np.median(ts) * 1e6)


def _placed(x: float) -> np.ndarray:
    """The pose of an arm's {w} at (x, 0, 0) in another's."""
    T = np.eye(4)
    T[:3, 3] = [x, 0.0, 0.0]
    return T


def main() -> None:
    p = RobotParams()
    lo, hi = psi_bounds(p)
    lo, hi = np.maximum(lo, -np.pi), np.minimum(hi, np.pi)  # delta is unbounded
    lo[1], hi[1] = 0.02, 0.08
    rng = np.random.default_rng(0)
    pairs = []
    for _ in range(200):
        qa, qb = rng.uniform(lo, hi), rng.uniform(lo, hi)
        T = np.eye(4)
        T[:3, 3] = [rng.uniform(0.03, 0.12), rng.uniform(-0.03, 0.03), 0.0]
        pairs.append((qa, qb, T))
    ref = [min_distance(body_capsules(p, qa, 64), transformed(body_capsules(p, qb, 64), T))[0] for qa, qb, T in pairs]
    out: dict[str, object] = {}
    q = np.array(HOME_PSI)
    near = transformed(body_capsules(p, [0.0, 0.12, 0.0, 0.0, 0.0, 0.0]), _placed(0.095))
    for K in (1, 2, 3, 4, 6, 8, 12):
        err = np.array([r - min_distance(body_capsules(p, qa, K), transformed(body_capsules(p, qb, K), T))[0]
                        for r, (qa, qb, T) in zip(ref, pairs)])
        out[f"K{K}"] = {
            "capsules": len(body_capsules(p, q, K)),
            "error_mean_mm": round(float(err.mean()) * 1e3, 4), "error_max_mm": round(float(err.max()) * 1e3, 4),
            "error_min_mm": round(float(err.min()) * 1e3, 6),
            "body_capsules_us": round(_median_us(lambda K=K: body_capsules(p, q, K), 500), 1),
            "clearance_rows_us": round(_median_us(lambda K=K: clearance_rows(p, q, near, 0.002, 0.06,
                                                                           per_segment=K), 500), 1),
        }
    cfg = dataclasses.replace(ControllerConfig(), backlash_compensation=False, ki=0.0)
    pc = tip_position(p, q)
    pd = pc + np.array([0.003, 0.002, -0.001])
    c = make_controller(p, cfg)
    out["velocity_us_no_obstacles"] = round(_median_us(lambda: c.velocity(q, pc, pd, np.zeros(3), 0.06), 5000), 2)
    far = transformed(body_capsules(p, q), _placed(0.6))
    c.set_obstacles(far, 0.002)
    out["velocity_us_obstacles_far"] = round(_median_us(lambda: c.velocity(q, pc, pd, np.zeros(3), 0.06)), 1)
    c.set_obstacles(near, 0.002)
    out["rows_near"] = int(len(c.clearance_rows(q, 0.06)[0]))  # type: ignore[attr-defined]
    out["velocity_us_obstacles_near"] = round(_median_us(lambda: c.velocity(q, pc, pd, np.zeros(3), 0.06)), 1)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
