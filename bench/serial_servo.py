"""Benchmark: the closed loop on the cube through the serial link vs in process.

Runs `wristmark servo`'s loop twice on the same trajectory, seed and noise: through protocol v1
on a pty to the in-process emulator (shared simulated clock), through DirectLink, and through a
DirectLink that rounds targets to micro-units as the wire does. Prints one JSON object:
closed-loop mean / max tip error of each, their differences, the largest per-cycle difference of
the true tip (serial vs direct; serial vs rounded direct: 0 means the pty adds nothing but the
rounding), wall time and requests per cycle.
Usage: .venv/bin/python bench/serial_servo.py [--duration S] [--sensor truth-noise|vision]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform

import numpy as np

from wristmark.cli import servo as S  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.rig.link import protocol as P  # noqa: E402
from wristmark.rig.link.actuator_link import DirectLink  # noqa: E402
from wristmark.rig.loop.servo_summary import summarize  # noqa: E402
from wristmark.sim.servo_bench import open_sim_session  # noqa: E402
from wristmark.sim.setup import load_setup  # noqa: E402


class RoundingDirectLink(DirectLink):
    """DirectLink rounding every target to protocol micro-units."""

    def send_target(self, actuators: np.ndarray) -> None:
        super().send_target(P.si_from_micro(P.micro_from_si(actuators)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, help="cut the cube walk to S seconds (default: all of it)")
    ap.add_argument("--sensor", default="truth-noise", choices=("truth-noise", "vision"))
    ap.add_argument("--image-scale", type=float, default=1.0)
    args = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    setup = load_setup()
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor=args.sensor, image_scale=args.image_scale))
    traj = S.build_trajectory(setup, "cube", None, args.duration)
    psi0 = S.start_configuration(setup, traj)
    runs = {}
    tips = {}
    for kind in ("emulator", "direct", "rounded"):
        session = open_sim_session(setup, psi0, S.LinkOptions(kind="direct" if kind == "rounded" else kind),
                                   seed=setup.rig.seed)
        if kind == "rounded":
            session.link = RoundingDirectLink(session.arm)
        out = S.run_servo(setup, traj, session, psi0, settle=setup.rig.settle_time)
        res = summarize(setup, traj, session, out)
        c = res["closed_loop"]
        runs[kind] = {"mean_mm": round(c["mean_mm"], 4), "max_mm": round(c["max_mm"], 4), "cycles": c["cycles"],
                      "stopped": out.stopped, "wall_time_s": round(out.wall_time_s, 2)}
        if kind == "emulator":
            runs[kind]["requests_per_cycle"] = round(res["link"]["sent"] / max(1, len(out.log.records)), 2)
            runs[kind]["retries"] = res["link"]["retries"]
        tips[kind] = np.array([r.p_true for r in out.log.records])
    a, b, c = tips["emulator"], tips["direct"], tips["rounded"]
    n = min(len(a), len(b), len(c))
    print(json.dumps({
        "bench": "serial_servo", "sensor": args.sensor, "duration_s": traj.duration,
        "serial": runs["emulator"], "direct": runs["direct"],
        "diff_mean_mm": round(runs["emulator"]["mean_mm"] - runs["direct"]["mean_mm"], 4),
        "diff_max_mm": round(runs["emulator"]["max_mm"] - runs["direct"]["max_mm"], 4),
        "max_cycle_tip_diff_mm": round(1000 * float(np.linalg.norm(a[:n] - b[:n], axis=1).max()), 4),
        "max_cycle_tip_diff_vs_rounded_direct_mm": float(1000 * np.linalg.norm(a[:n] - c[:n], axis=1).max()),
        "python": platform.python_version(),
    }, indent=2))


if __name__ == "__main__":
    main()
