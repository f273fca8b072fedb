"""Benchmark: FK + 6 x n tip Jacobian of any arm (models.arm_kinematics) against today's 6-DoF
reference chain (models.kinematics) measured in the same process, interleaved.

Prints one JSON object: per arm the median over repeats of the per-call mean [us] and the ratio
to the reference chain's median ("ratio"), and the ratio per segment relative to the reference
arm's two ("ratio_per_segment" = ratio / (segments / 2)); also the batch path per configuration.
Usage: .venv/bin/python bench/arm_kinematics.py [--calls 1000] [--repeats 15]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import numpy as np

from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian
from wristmark.models.arm_spec import ArmSpec, load_arm, shipped_robot_files
from wristmark.models.kinematics import forward_kinematics, tip_jacobian
from wristmark.models.robot_params import RobotParams


def _psis(spec: ArmSpec, n: int, seed: int = 0) -> np.ndarray:
    lo, hi = spec.bounds()
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    return np.random.default_rng(seed).uniform(lo, hi, (n, spec.n))


def _time(fn: Callable[[np.ndarray], object], psis: np.ndarray) -> float:
    t0 = time.perf_counter()
    for psi in psis:
        fn(psi)
    return (time.perf_counter() - t0) / len(psis)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--calls", type=int, default=1000, help="configurations per repeat")
    ap.add_argument("--repeats", type=int, default=15, help="repeats (median taken)")
    args = ap.parse_args()
    params = RobotParams()
    arms = {"reference (robot.yaml)": ArmSpec.from_params(params)}
    arms |= {p.name: load_arm(p) for p in shipped_robot_files()}
    ref_psis = list(_psis(arms["reference (robot.yaml)"], args.calls))

    def today(psi: np.ndarray) -> object:
        return tip_jacobian(params, psi, forward_kinematics(params, psi))

    fns: dict[str, tuple[Callable[[np.ndarray], object], np.ndarray]] = {"today": (today, np.array(ref_psis))}
    for name, spec in arms.items():
        fns[name] = ((lambda s: lambda psi: arm_tip_jacobian(s, psi, arm_frames(s, psi)))(spec),
                     _psis(spec, args.calls))
    times: dict[str, list[float]] = {k: [] for k in fns}
    for fn, psis in fns.values():
        _time(fn, psis[:50])  # warm-up
    for _ in range(args.repeats):
        for k, (fn, psis) in fns.items():  # interleaved: load drifts hit every entry alike
            times[k].append(_time(fn, psis))
    med = {k: float(np.median(v) * 1e6) for k, v in times.items()}
    out: dict[str, object] = {"calls": args.calls, "repeats": args.repeats, "today_us": med["today"], "arms": {}}
    for name, spec in arms.items():
        batch = _psis(spec, args.calls)
        t0 = time.perf_counter()
        arm_tip_jacobian(spec, batch, arm_frames(spec, batch))
        ratio = med[name] / med["today"]
        out["arms"][name] = {  # type: ignore[index]
            "n": spec.n, "segments": len(spec.segments), "fk_plus_jacobian_us": med[name],
            "ratio": ratio, "ratio_per_segment": ratio / (len(spec.segments) / 2),
            "batch_us_per_config": (time.perf_counter() - t0) / args.calls * 1e6,
        }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
