"""Run a sweep's trials on dask.distributed; results.csv written as they finish; resume.

``DIR/sweep.json`` records the SPEC and a fingerprint of its trials (options and configuration
contents). A folder holding the same sweep resumes: the rows already in ``DIR/results.csv`` are
kept and only the missing trials run; a folder holding anything else is refused. Rows are
appended (and flushed) as trials finish, in whatever order; the complete file is rewritten in
trial order at the end. A trial's failure is a row; an interrupted sweep loses only the trials
that were running. A finished trial, ok or not, is never run again: delete its row from
results.csv to run it again.
"""

from __future__ import annotations

import csv
import functools
import io
import json
import logging
import math
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from wristmark.models.errors import InputError
from wristmark.sweep.keys import format_value
from wristmark.sweep.spec import SweepSpec
from wristmark.sweep.trial import (
    THREAD_ENV,
    TrialJob,
    metric_columns,
    one_line,
    run_trial,
    tracks_frames,
    warm_up,
)

if TYPE_CHECKING:
    from distributed import Client

RESULTS = "results.csv"
RECORD = "sweep.json"
FINAL = ("status", "wall_s", "worker")


@dataclass(frozen=True)
class SweepOutcome:
    """What a sweep did: trials found done in DIR, trials run now, failed trials, wall time [s]
    (all of it; ``trials_s``: from the first trial submitted to the last one finished)."""

    total: int
    resumed: int
    ran: int
    failed: int
    wall_s: float
    trials_s: float


def columns(spec: SweepSpec) -> list[str]:
    """results.csv header: trial, seed, the swept keys as written, the metrics, status, wall_s, worker."""
    return ["trial", "seed", *spec.swept_keys, *metric_columns(spec.experiment), *FINAL]


def cell(value: Any) -> str:
    """One CSV cell: floats exactly (repr), None empty."""
    if value is None:
        return ""
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    return format_value(value)


def read_rows(path: Path, header: list[str]) -> dict[int, dict[str, str]]:
    """Complete rows of a results.csv by trial (a line cut by a kill is dropped)."""
    if not path.is_file():
        return {}
    text = path.read_text()
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    reader = csv.reader(io.StringIO(text))
    first = next(reader, None)
    if first is None:
        return {}
    if first != header:
        raise InputError(f"{path}: its header is not this sweep's; use a new --out DIR")
    rows: dict[int, dict[str, str]] = {}
    for values in reader:
        if len(values) == len(header) and values[0].isdigit() and values[header.index("status")]:
            rows.setdefault(int(values[0]), dict(zip(header, values)))
    return rows


def write_rows(path: Path, header: list[str], rows: list[dict[str, str]]) -> None:
    """Write a complete results.csv atomically."""
    tmp = path.with_suffix(".csv.tmp")
    with tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow([r.get(k, "") for k in header])
    os.replace(tmp, path)


def prepare_folder(spec: SweepSpec, out: Path) -> dict[int, dict[str, str]]:
    """Create DIR or check it holds this sweep; the rows already done (matching their trials)."""
    record = out / RECORD
    fingerprint = spec.fingerprint()
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()):
        if not record.is_file():
            raise InputError(f"--out {out} is not empty and holds no sweep ({RECORD}); use a new or empty folder")
        try:
            held = json.loads(record.read_text()).get("fingerprint")
        except (json.JSONDecodeError, AttributeError):
            held = None
        if held != fingerprint:
            raise InputError(f"--out {out} holds a different sweep (another SPEC, or its configuration files "
                             "changed); use a new --out DIR to run this one")
    else:
        out.mkdir(parents=True, exist_ok=True)
        record.write_text(json.dumps({"spec": spec.describe(), "spec_file": str(spec.path),
                                      "fingerprint": fingerprint}, indent=2) + "\n")
    header = columns(spec)
    done = read_rows(out / RESULTS, header)
    keep = {}
    for t in spec.trials:
        r = done.get(t.index)
        if r is not None and r["seed"] == str(t.seed) and all(r[k] == cell(v) for k, v in t.values.items()):
            keep[t.index] = r
    write_rows(out / RESULTS, header, [keep[i] for i in sorted(keep)])
    return keep


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None) -> Iterator[Client]:
    """A client of the scheduler at ``scheduler``, or of a new LocalCluster of ``workers``
    single-threaded worker processes (default: the machine's cores), closed afterwards."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="5s")
        except (OSError, TimeoutError, ValueError) as e:
            raise InputError(f"cannot reach the dask scheduler at {scheduler}: {one_line(str(e))}") from None
        try:
            yield client
        finally:
            client.close()
        return
    cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR, env=THREAD_ENV)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def run_sweep(spec: SweepSpec, out: Path, workers: int | None = None, scheduler: str | None = None,
              progress: bool = True) -> SweepOutcome:
    """Run the trials of ``spec`` missing from ``out``; results.csv, then summary.md."""
    from tqdm import tqdm

    from wristmark.sweep.report import write_summary

    t0 = time.perf_counter()
    shown, out = out, out.resolve()
    done = prepare_folder(spec, out)
    header = columns(spec)
    todo = [t for t in spec.trials if t.index not in done]
    if done:
        print(f"resuming: {len(done)} of {len(spec.trials)} trials already in {out / RESULTS}, "
              f"running the other {len(todo)}", file=sys.stderr)
    failed = sum(r["status"] != "ok" for r in done.values())
    trials_s = 0.0
    if todo:
        with dask_client(workers, scheduler) as client, (out / RESULTS).open("a", newline="") as f, \
                tqdm(total=len(spec.trials), initial=len(done), unit="trial", desc="sweep", disable=not progress,
                     file=sys.stderr, dynamic_ncols=True) as bar:
            try:
                client.run(functools.partial(warm_up, jit=any(tracks_frames(t.args) for t in todo)))
            except Exception as e:  # noqa: BLE001 - e.g. a remote worker without wristmark installed
                raise InputError(f"the dask workers cannot prepare a trial: {one_line(f'{type(e).__name__}: {e}')}"
                                 ) from None
            writer = csv.writer(f)
            t_submit = time.perf_counter()
            tag = spec.fingerprint()[:10]
            futures = {client.submit(run_trial, TrialJob(spec.experiment, t, str(out / "trials" / f"{t.index:04d}")),
                                     key=f"wristmark-trial-{tag}-{t.index:05d}", pure=False): t for t in todo}
            from distributed import as_completed

            for fut in as_completed(list(futures)):
                t = futures[fut]
                try:
                    row = fut.result()
                except Exception as e:  # noqa: BLE001 - a lost worker fails its trial, not the sweep
                    row = {"status": one_line(f"error: {type(e).__name__}: {e}"), "wall_s": math.nan, "worker": ""}
                row.update({"trial": t.index, "seed": t.seed, **t.values})
                writer.writerow([cell(row.get(k)) for k in header])
                f.flush()
                failed += row["status"] != "ok"
                bar.update(1)
                bar.set_postfix(failed=failed, refresh=False)
                fut.release()
            trials_s = time.perf_counter() - t_submit
    rows = read_rows(out / RESULTS, header)
    ordered = [rows[i] for i in sorted(rows)]
    write_rows(out / RESULTS, header, ordered)
    write_summary(spec, out, ordered, shown)
    return SweepOutcome(len(spec.trials), len(done), len(todo), failed, time.perf_counter() - t0, trials_s)
