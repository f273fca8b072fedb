"""One sweep trial: a ``wristmark experiment`` run in this process, from its options and seed.

The trial writes its changed configuration files and runs the command line itself
(:func:`wristmark.cli.main.main`), so a trial and ``wristmark experiment`` share one code path and
``TRIAL_DIR/command.txt`` reproduces it by hand. Its output goes to ``TRIAL_DIR/output.txt``,
the run folder to ``TRIAL_DIR/run``, the result JSON to ``TRIAL_DIR/result.json``. Whatever
happens (a safe stop, a bad value, an exception) the trial returns a row with its status:
``ok``, ``stopped: <reason>`` or ``error: <one line>``. Nothing in the row but ``wall_s`` and
``worker`` depends on where or when the trial ran.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import shlex
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wristmark.sweep.keys import write_configs
from wristmark.sweep.spec import Trial

# Library thread pools held to one thread: N workers on N cores must not fight over them.
THREAD_ENV = {name: "1" for name in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                     "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")}
CORE_METRICS = ("open_mean_mm", "open_max_mm", "closed_mean_mm", "closed_max_mm", "ratio")
EXTRA_METRICS = {
    "cube": ("closed_rms_mm", "closed_p95_mm", "lost", "rejected"),
    "point": ("closed_rms_mm", "closed_p95_mm", "lost", "rejected"),
    "load": (),
    "accuracy": ("accuracy_mean_mm", "accuracy_max_mm", "tracked"),
}
_pinned: list[Any] = []  # the threadpoolctl limiter, kept alive for the process


def metric_columns(experiment: str) -> list[str]:
    """Metric columns of a sweep of ``experiment``, in results.csv order."""
    return [*CORE_METRICS, *EXTRA_METRICS.get(experiment, ())]


def pin_threads() -> None:
    """Hold numba, OpenCV and the BLAS/OpenMP pools of this process to one thread (once)."""
    if _pinned:
        return
    numba_loaded = "numba" in sys.modules  # it read NUMBA_NUM_THREADS at import: set_num_threads below does it
    for k, v in THREAD_ENV.items():
        if not (numba_loaded and k == "NUMBA_NUM_THREADS"):  # changed under a started pool, numba's next
            os.environ.setdefault(k, v)  # compilation raises RuntimeError (a trial run in an existing process)
    import cv2
    import numba
    from threadpoolctl import threadpool_limits

    cv2.setNumThreads(1)
    numba.set_num_threads(1)
    _pinned.append(threadpool_limits(limits=1))


def warm_up(jit: bool = True) -> str:
    """Pin the threads and import what a trial needs (run on every worker before the trials, so
    that a trial's wall time is its own), with ``jit`` the tracker's kernels too (trials that
    track rendered frames); the worker's name."""
    pin_threads()
    import wristmark.cli.experiment  # noqa: F401
    import wristmark.cli.main  # noqa: F401
    import wristmark.sim.experiments  # noqa: F401
    from wristmark.cvs.tracking.warmup import warm_up as warm_up_process

    warm_up_process(jit=jit)  # the tracker's kernels, loaded before the first trial (cvs.tracking.warmup)

    return worker_name()


def tracks_frames(args: tuple[str, ...]) -> bool:
    """Whether a trial with these ``wristmark experiment`` option words may track rendered frames:
    every trial but those that ask for ``--sensor truth-noise`` (a rig file may still choose it)."""
    words = list(args)
    for k, w in enumerate(words):
        if w == "--sensor=truth-noise" or (w == "--sensor" and words[k + 1 : k + 2] == ["truth-noise"]):
            return False
    return True


@dataclass(frozen=True)
class TrialJob:
    """What a worker needs to run one trial: the experiment, the trial, its folder (absolute)."""

    experiment: str
    trial: Trial
    folder: str


def worker_name() -> str:
    """The dask worker's address, or ``local`` outside a worker."""
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return "local"


def run_trial(job: TrialJob) -> dict[str, Any]:
    """Run one trial; its results.csv row (metrics, status, wall_s, worker; no swept values)."""
    pin_threads()
    t0 = time.perf_counter()
    folder = Path(job.folder)
    shutil.rmtree(folder, ignore_errors=True)  # a trial cut short by a killed sweep starts afresh
    folder.mkdir(parents=True)
    row: dict[str, Any] = {"trial": job.trial.index, "seed": job.trial.seed}
    try:
        words = write_configs(job.trial.configs, folder / "config")
        argv = [*job.trial.argv(job.experiment, words), "--no-progress", "--out", str(folder / "run"),
                "--json", str(folder / "result.json")]
        (folder / "command.txt").write_text(shlex.join(["wristmark", *argv]) + "\n")
        code, err = _run_cli(argv, folder / "output.txt")
        result = folder / "result.json"
        res = json.loads(result.read_text()) if result.is_file() else None
        if res is not None:
            row.update(metrics_of(job.experiment, res))
        row["status"] = _status(code, err, res)
    except Exception as e:  # noqa: BLE001 - a trial's failure is a row, never a crashed sweep
        row["status"] = one_line(f"error: {type(e).__name__}: {e}")
    row["wall_s"] = time.perf_counter() - t0
    row["worker"] = worker_name()
    return row


def _run_cli(argv: list[str], log: Path) -> tuple[int, str]:
    """``wristmark ARGV`` in this process; (exit code, stderr). stdout+stderr go to ``log``."""
    from wristmark.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse refusing the command line
            code = e.code if isinstance(e.code, int) else 2
    log.write_text(out.getvalue() + err.getvalue())
    return code, err.getvalue()


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line, at most ``limit`` characters."""
    line = " ".join(text.split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def _status(code: int, stderr: str, res: dict[str, Any] | None) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    last = lines[-1] if lines else f"exit status {code}"
    if code == 0 and res is not None:
        return "ok"
    if code == 3:
        return one_line("stopped: " + last.split("stopped safely: ", 1)[-1])
    if code == 0:
        return "error: the experiment wrote no result"
    return one_line("error: " + last.split(": error: ", 1)[-1])


def metrics_of(experiment: str, res: dict[str, Any]) -> dict[str, Any]:
    """The metric columns of one experiment's result JSON (load: over all its forces)."""
    if experiment == "accuracy":
        return {"accuracy_mean_mm": res["mean_mm"], "accuracy_max_mm": res["max_mm"], "tracked": res["tracked"]}
    if experiment == "load":
        phases = {"open": [r["open_loop"] for r in res["rows"]], "closed": [r["closed_loop"] for r in res["rows"]]}
        out = {f"{k}_mean_mm": sum(p["mean_mm"] for p in v) / len(v) for k, v in phases.items()}
        out.update({f"{k}_max_mm": max(p["max_mm"] for p in v) for k, v in phases.items()})
        out["ratio"] = out["closed_mean_mm"] / out["open_mean_mm"] if out["open_mean_mm"] else math.nan
        return out
    o, c = res["open_loop"], res["closed_loop"]
    return {"open_mean_mm": o["mean_mm"], "open_max_mm": o["max_mm"], "closed_mean_mm": c["mean_mm"],
            "closed_max_mm": c["max_mm"], "ratio": res["ratio"], "closed_rms_mm": c["rms_mm"],
            "closed_p95_mm": c["p95_mm"], "lost": c["lost"], "rejected": c["rejected"]}
