"""A servo run's record as an identification's excitation (``wristmark identify --from-log RUN``,
docs/identification.md "From a servo run").

A run folder's ``log.csv`` (rig/recording/run_log.py) has, per cycle, what the actuator box last
saw (``t_act``, ``act_cmd_<name>``, ``act_meas_<name>``) and, at the cycles that tracked the
marker, the tip measured in {w} (``p_est``) from a frame captured at ``t_capture`` (same clock as
``t_act``). The tip was seen in motion, so each measured tip gets its own row: the encoders
interpolated to the frame's capture time (the arm's shape follows its encoders through the plays,
without dynamics of its own: models/plant_map.py), the target in force then. Times [s],
actuators [rad or m], tips [m].
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm, actuator_names, log_psi_names
from wristmark.models.errors import InputError
from wristmark.rig.recording.run_log import read_log_csv
from wristmark.solvers.identification import ExcitationData

Array = NDArray[np.float64]
__all__ = ["excitation_from_run"]

LOG_NAME = "log.csv"


def _column(cols: dict[str, Array | list[str]], name: str) -> Array:
    return np.asarray(cols[name], float)


def _on_one_clock(t: Array) -> tuple[Array, NDArray[np.int_]]:
    """The readings' times [s] of a log whose phases may each start their own clock
    (``experiment``'s open and closed loops each run a fresh simulated arm from t = 0), shifted to
    follow each other (a time that runs back begins a new stretch one median cycle after the
    last), and each row's stretch (0, 1, ...; a new stretch is a fresh arm)."""
    out = np.array(t, float)
    good = np.isfinite(out)
    step = np.diff(out[good])
    cycle = float(np.median(step[step > 0])) if np.any(step > 0) else 0.0
    stretch = np.zeros(out.size, dtype=int)
    shift, last, n = 0.0, -np.inf, 0
    for k in range(out.size):
        if good[k] and out[k] + shift <= last:
            shift, n = last + cycle - out[k], n + 1
        out[k] += shift
        stretch[k] = n
        if good[k]:
            last = out[k]
    return out, stretch


def excitation_from_run(folder: str | Path, arm: Arm) -> ExcitationData:
    """The excitation recorded by a servo run (``wristmark servo``/``experiment`` ``--out RUN``)
    of ``arm``: every cycle's encoders and target, and every tracked tip at its frame's capture;
    InputError when the log is missing, of another arm, or older than the act_ columns."""
    path = Path(folder) / LOG_NAME
    try:
        cols = read_log_csv(path)
    except (OSError, UnicodeDecodeError, ValueError, KeyError, csv.Error) as e:
        raise InputError(f"{path}: not a readable run log ({e})") from None
    if not cols:
        raise InputError(f"{path}: no logged cycles")
    names = actuator_names(arm)
    want = ["t_act", "t_capture", "meas_ok"] + [f"act_{k}_{a}" for k in ("cmd", "meas") for a in names]
    missing = [c for c in want if c not in cols]
    if missing:
        raise InputError(f"{path}: no column '{missing[0]}' (a run of another arm, or written before the log kept "
                         "the actuators' readings)")
    t, stretch = _on_one_clock(_column(cols, "t_act"))
    cap = _column(cols, "t_capture") + (t - _column(cols, "t_act"))  # each capture shifted as its stretch
    enc = np.column_stack([_column(cols, f"act_meas_{a}") for a in names])
    tgt = np.column_stack([_column(cols, f"act_cmd_{a}") for a in names])
    rows = np.isfinite(t) & np.isfinite(enc).all(axis=1) & np.isfinite(tgt).all(axis=1)
    if rows.sum() < 2:
        raise InputError(f"{path}: fewer than 2 cycles with the actuators' readings")
    # each stretch's span of readings: a tip is kept only inside its own stretch's
    first = {int(n): float(np.min(t[rows & (stretch == n)])) for n in np.unique(stretch[rows])}
    final = {int(n): float(np.max(t[rows & (stretch == n)])) for n in np.unique(stretch[rows])}
    row_stretch = stretch.copy()
    order = np.argsort(t[rows], kind="stable")
    t, enc, tgt, stretch = t[rows][order], enc[rows][order], tgt[rows][order], stretch[rows][order]
    keep = np.r_[True, np.diff(t) > 0]  # one reading per instant
    t, enc, tgt, stretch = t[keep], enc[keep], tgt[keep], stretch[keep]

    tags = log_psi_names(arm) or tuple(str(i) for i in range(6))
    psi_cmd = np.column_stack([_column(cols, f"psi_cmd_{i}") for i in tags])
    tip = np.column_stack([_column(cols, f"p_est_{a}") for a in "xyz"])
    seen = (_column(cols, "meas_ok") > 0) & np.isfinite(tip).all(axis=1) & np.isfinite(cap)
    lo = np.array([first.get(int(n), np.inf) for n in row_stretch])
    hi = np.array([final.get(int(n), -np.inf) for n in row_stretch])
    seen &= (cap >= lo) & (cap <= hi)  # inside its stretch's readings: interpolated, never extrapolated
    cap, tip, hint = cap[seen], tip[seen], psi_cmd[seen]

    # one row per tracked tip at its capture time, merged into the cycles' rows
    at = np.searchsorted(t, cap, side="right") - 1  # the last reading at or before the capture
    enc_cap = np.column_stack([np.interp(cap, t, enc[:, j]) for j in range(enc.shape[1])])
    times = np.concatenate([t, cap])
    encoders = np.vstack([enc, enc_cap])
    targets = np.vstack([tgt, tgt[np.clip(at, 0, len(t) - 1)]])
    merged = np.argsort(times, kind="stable")
    position = np.empty_like(merged)
    position[merged] = np.arange(merged.size)
    sample_index = position[len(t):]
    by_time = np.argsort(sample_index, kind="stable")
    restarts = tuple(int(position[k]) for k in np.flatnonzero(np.diff(stretch) > 0) + 1)
    return ExcitationData(times[merged], encoders[merged], targets[merged], sample_index[by_time].astype(int),
                          tip[by_time], hint[by_time],
                          {"motion_s": float(t[-1] - t[0]), "poses": int(seen.sum()), "source": "servo run"},
                          restarts)
