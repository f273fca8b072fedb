"""Benchmark: time per FK + 6x6 tip Jacobian, closed form vs Pinocchio (several N).

Prints one JSON object on stdout. Times are medians over repeats of the per-call mean
[microseconds]; configurations are random within the joint limits (seeded).
Usage: .venv/bin/python bench/kinematics.py [--calls 2000] [--repeats 15]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable

import numpy as np

from wristmark.models.kinematics import forward_kinematics, tip_jacobian, tip_position  # noqa: E402
from wristmark.models.pinocchio_model import PinocchioArm  # noqa: E402
from wristmark.models.robot_params import RobotParams  # noqa: E402

AIM_US = 50.0  # target for the controller's path [us]


def _random_psis(params: RobotParams, n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    lo = [params.phi_range[0], params.d_range[0], 0.0, -np.pi, 0.0, -np.pi]
    hi = [
        params.phi_range[1],
        params.d_range[1],
        params.theta_max[0],
        np.pi,
        params.theta_max[1],
        np.pi,
    ]
    return [rng.uniform(lo, hi) for _ in range(n)]


def median_us(fn: Callable[[np.ndarray], object], psis: list[np.ndarray], repeats: int) -> float:
    """Median over ``repeats`` of the mean time per call of ``fn`` over ``psis`` [us]."""
    for psi in psis[:50]:
        fn(psi)  # warm-up
    per_call = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for psi in psis:
            fn(psi)
        per_call.append((time.perf_counter() - t0) / len(psis))
    return float(np.median(per_call) * 1e6)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--calls", type=int, default=2000, help="configurations per repeat")
    ap.add_argument("--repeats", type=int, default=15, help="repeats (median taken)")
    ap.add_argument("--links", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    args = ap.parse_args()

    params = RobotParams()
    psis = _random_psis(params, args.calls)

    def closed_fk_jac(psi: np.ndarray) -> object:
        fr = forward_kinematics(params, psi)
        return tip_jacobian(params, psi, fr)

    result: dict[str, object] = {
        "machine": platform.machine(),
        "python": platform.python_version(),
        "calls": args.calls,
        "repeats": args.repeats,
        "aim_us": AIM_US,
        "closed_form": {
            "tip_position_us": median_us(lambda p: tip_position(params, p), psis, args.repeats),
            "fk_us": median_us(lambda p: forward_kinematics(params, p), psis, args.repeats),
            "jacobian_us": median_us(lambda p: tip_jacobian(params, p), psis, args.repeats),
            "fk_plus_jacobian_us": median_us(closed_fk_jac, psis, args.repeats),
        },
    }
    pin_results = {}
    for n in args.links:
        arm = PinocchioArm(params, n)
        pin_results[str(n)] = {
            "nq": int(arm.model.nq),
            "fk_us": median_us(arm.forward, psis, args.repeats),
            "jacobian_us": median_us(arm.tip_jacobian, psis, args.repeats),
            "fk_plus_jacobian_us": median_us(
                lambda p, a=arm: (a.forward(p), a.tip_jacobian(p)), psis, args.repeats
            ),
        }
    result["pinocchio"] = pin_results
    closed = result["closed_form"]
    assert isinstance(closed, dict)
    result["controller_path"] = "closed_form"
    result["controller_path_under_aim"] = bool(closed["fk_plus_jacobian_us"] < AIM_US)
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
