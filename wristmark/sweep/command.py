"""``wristmark sweep SPEC.yaml --out DIR [--workers N | --scheduler ADDRESS]``: many seeded
experiment runs over a grid and/or random samples of options and configuration keys, on
dask.distributed (docs/design.md "Sweeps"; the SPEC: sweep/spec.py).

Every trial is checked before any starts (a bad SPEC: one line, exit 2). ``DIR/results.csv``
gains a row as each trial finishes; run the same command again to finish an interrupted sweep.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from wristmark.cli.common_options import set_example
from wristmark.cli.option_types import int_in


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("spec", metavar="SPEC.yaml", help="the sweep: experiment, set, grid, random, seeds")
    p.add_argument("--out", metavar="DIR", required=True,
                   help="output folder: results.csv, summary.md, plots/, trials/ (same SPEC: resumes)")
    set_example(p, "wristmark sweep configs/sweeps/latency_backlash.yaml --out runs/latency_backlash")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int_in(1, 1024), metavar="N",
                       help="start a local cluster of N single-threaded worker processes (default: the cores)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use the running dask cluster at ADDRESS (e.g. tcp://10.0.0.5:8786)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from wristmark.sweep.report import summary_table
    from wristmark.sweep.run import RESULTS, columns, read_rows, run_sweep
    from wristmark.sweep.spec import load_spec

    spec = load_spec(args.spec)
    out = Path(args.out)
    outcome = run_sweep(spec, out, workers=args.workers, scheduler=args.scheduler, progress=not args.no_progress)
    rows = read_rows(out / RESULTS, columns(spec))
    print(summary_table(spec, [rows[i] for i in sorted(rows)]))
    print(f"{outcome.total} trials ({outcome.resumed} found done, {outcome.ran} run now) in {outcome.wall_s:.1f} s: "
          f"{out / RESULTS}, {out / 'summary.md'}")
    if outcome.failed:
        print(f"wristmark sweep: {outcome.failed} of {outcome.total} trials did not finish ok "
              f"(their status is in {out / RESULTS})", file=sys.stderr)
    return 0
