"""Benchmark: time per controller step (paper, qp) and per raw QP solve; steps to converge.

Prints JSON. Medians of many calls; ratio of qp to paper measured in the same run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import sys
import time
from collections.abc import Iterator

import numpy as np

from wristmark.models.config_files import default_config
from wristmark.models.kinematics import tip_position
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller
from wristmark.solvers.qp_controller import BoxQp


@contextlib.contextmanager
def _stdout_to_stderr() -> Iterator[None]:
    """Send C-level stdout to stderr (qpOASES prints its licence banner there): stdout stays JSON."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _median_us(fn, n: int = 2000) -> float:  # type: ignore[no-untyped-def]
    ts = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t0
    return float(np.median(ts) * 1e6)


def main() -> None:
    p = RobotParams()
    q = np.array(HOME_PSI)
    pc = tip_position(p, q)
    pd = pc + np.array([0.003, 0.002, -0.001])
    out: dict[str, object] = {}
    for kind in ("paper", "qp"):
        # the plain controllers (no dead-band inversion, integral or probe): their step alone
        plain = ControllerConfig.load(default_config("controller_plain.yaml"))
        c = make_controller(p, dataclasses.replace(plain, kind=kind, saturate_near_target=True))
        out[f"{kind}_step_us_median"] = _median_us(lambda c=c: c.step(q, pc, pd, np.zeros(3), 0.06))
        qq = q.copy()
        steps = 0
        while np.linalg.norm(tip_position(p, qq) - pd) > 1e-5 and steps < 200:
            qq = c.step(qq, tip_position(p, qq), pd, np.zeros(3), 0.06).psi_next
            steps += 1
        out[f"{kind}_steps_to_10um"] = steps
    qp = BoxQp("daqp")
    rng = np.random.default_rng(0)
    A = rng.normal(size=(9, 6))
    b = rng.normal(size=9)
    H, g = 2 * A.T @ A, -2 * A.T @ b
    lo, hi = -np.ones(6), np.ones(6)
    out["qp_raw_solve_us_median_daqp"] = _median_us(lambda: qp.solve(H, g, lo, hi))
    with _stdout_to_stderr():  # qpOASES's licence banner
        qpo = BoxQp("qpoases")
        qpo.solve(H, g, lo, hi)
    out["qp_raw_solve_us_median_qpoases"] = _median_us(lambda: qpo.solve(H, g, lo, hi))
    out["qp_over_paper_step_ratio"] = out["qp_step_us_median"] / out["paper_step_us_median"]  # type: ignore[operator]
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
