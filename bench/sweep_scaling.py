"""Sweep throughput on this machine: trials per minute with 1 and 2 dask workers (LocalCluster),
against the same trials in a plain loop in one process; prints JSON.

Each configuration runs ``--repeats`` times, interleaved (plain, 1 worker, 2 workers, plain, ...)
so that a change in the machine's load hits all three alike; medians are reported. ``trials_s``
is the time from the first trial submitted to the last one finished (cluster start-up, warm-up
and summary excluded); ``wall_s`` is the whole ``run_sweep``. The engine's overhead per trial is
``(trials_s with 1 worker - plain loop) / n`` across runs, and, within one run (robust to the
machine's load changing between runs), ``(trials_s - sum of the trials' own wall_s) / n``: the
time a trial spends outside its experiment (dispatch, transfer, the CSV row). The machine's load
(load average, the busiest other processes) is sampled before and after, since it is shared.

    .venv/bin/python bench/sweep_scaling.py [--trials 8] [--duration 4] [--repeats 2]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def machine_load() -> dict:
    """Load average and the other processes using more than 10 % of a core over one second."""
    import psutil

    me = {os.getpid(), *(c.pid for c in psutil.Process().children(recursive=True))}
    procs = [p for p in psutil.process_iter(["pid", "name", "cmdline"]) if p.pid not in me]
    for p in procs:
        try:
            p.cpu_percent(None)
        except psutil.Error:
            pass
    time.sleep(1.0)
    busy = []
    for p in procs:
        try:
            cpu = p.cpu_percent(None)
        except psutil.Error:
            continue
        if cpu > 10:
            cmd = " ".join(p.info["cmdline"] or [p.info["name"] or "?"])
            busy.append({"cpu_percent": round(cpu), "command": cmd[:100]})
    busy.sort(key=lambda b: -b["cpu_percent"])
    return {"loadavg_1_5_15": [round(x, 2) for x in os.getloadavg()], "cores": os.cpu_count(),
            "busy_other_processes": busy[:8]}


def main() -> None:
    from wristmark.sweep.run import run_sweep
    from wristmark.sweep.spec import load_spec
    from wristmark.sweep.trial import TrialJob, run_trial, warm_up

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--duration", type=float, default=4.0, help="cube seconds per trial")
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="wristmark-sweep-bench-"))
    spec_path = tmp / "spec.yaml"
    spec_path.write_text(f"experiment: cube\nset: {{sensor: truth-noise, duration: {a.duration}}}\n"
                         f"seeds: {list(range(a.trials))}\n")
    spec = load_spec(spec_path)
    n = len(spec.trials)
    load_before = machine_load()
    warm_up()
    runs: dict[str, list[dict]] = {"plain_loop": [], "workers_1": [], "workers_2": []}
    for rep in range(a.repeats):
        t0 = time.perf_counter()
        rows = [run_trial(TrialJob(spec.experiment, t, str(tmp / f"plain{rep}" / f"{t.index:04d}")))
                for t in spec.trials]
        plain = time.perf_counter() - t0
        runs["plain_loop"].append({"trials_s": plain, "wall_s": plain, "ok": sum(r["status"] == "ok" for r in rows),
                                   "sum_trial_wall_s": sum(r["wall_s"] for r in rows)})
        for w in (1, 2):
            out = run_sweep(spec, tmp / f"w{w}-{rep}", workers=w, progress=False)
            with open(tmp / f"w{w}-{rep}" / "results.csv", newline="") as f:
                walls = [float(r["wall_s"]) for r in csv.DictReader(f)]
            runs[f"workers_{w}"].append({"trials_s": out.trials_s, "wall_s": out.wall_s, "ok": n - out.failed,
                                         "sum_trial_wall_s": sum(walls)})

    def med(name: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[name])

    per_min = {k: 60.0 * n / med(k, "trials_s") for k in runs}
    result = {
        "trials": n, "trial": f"cube, truth-noise, {a.duration} s of the walk (+ settle), open + closed loop",
        "repeats": a.repeats,
        "trials_per_minute": {k: round(v, 2) for k, v in per_min.items()},
        "trials_per_minute_end_to_end": {k: round(60.0 * n / med(k, "wall_s"), 2) for k in runs},
        "ratio_2_workers_over_1": round(per_min["workers_2"] / per_min["workers_1"], 3),
        "ratio_2_workers_over_1_end_to_end": round(med("workers_1", "wall_s") / med("workers_2", "wall_s"), 3),
        "engine_overhead_per_trial_s": round((med("workers_1", "trials_s") - med("plain_loop", "trials_s")) / n, 3),
        "engine_overhead_per_trial_same_run_s": {
            k: round(statistics.median((r["trials_s"] - r["sum_trial_wall_s"]) / n for r in runs[k]), 4)
            for k in ("plain_loop", "workers_1")},
        "engine_fixed_cost_s": {k: round(med(k, "wall_s") - med(k, "trials_s"), 2) for k in ("workers_1", "workers_2")},
        "median_s": {k: {"trials_s": round(med(k, "trials_s"), 2), "wall_s": round(med(k, "wall_s"), 2)} for k in runs},
        "runs": runs,
        "machine_before": load_before,
        "machine_after": machine_load(),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
