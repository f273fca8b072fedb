"""Tracking-error metrics of a logged phase: errors, corner overshoot (reported in mm)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.rig.run_log import CycleRecord

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ErrorStats:
    """Distances between a measured and the desired tip [mm]."""

    mean_mm: float
    max_mm: float
    rms_mm: float
    p95_mm: float
    n: int

    def as_dict(self) -> dict[str, float]:
        """Plain dict for JSON."""
        return asdict(self)


def error_stats(errors_m: Array) -> ErrorStats:
    """Statistics of an array of distances [m], reported in mm."""
    e = 1000.0 * np.asarray(errors_m, float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        nan = float("nan")
        return ErrorStats(nan, nan, nan, nan, 0)
    return ErrorStats(float(e.mean()), float(e.max()), float(np.sqrt(np.mean(e**2))),
                      float(np.percentile(e, 95)), int(e.size))


def tracking_errors(records: list[CycleRecord], which: str = "p_trk") -> Array:
    """|p_which - p_des| per record [m] (which: p_trk tracker, p_true noise-free, p_est vision)."""
    out = []
    for r in records:
        p = getattr(r, which)
        out.append(np.nan if p is None else float(np.linalg.norm(np.asarray(p) - r.p_des)))
    return np.asarray(out)


def estimate_errors(records: list[CycleRecord]) -> Array:
    """|p_est - p_true| per record [m]: the vision estimate against the true tip at capture (nan
    where there was no estimate)."""
    return np.asarray([np.nan if r.p_est is None else float(np.linalg.norm(np.asarray(r.p_est) - r.p_true))
                       for r in records])


def corner_overshoot(records: list[CycleRecord], waypoints: Array, times: Array, window: float = 1.0) -> Array:
    """Overshoot at each corner of a piecewise-linear desired path [m].

    ``waypoints`` (N,3) and their arrival ``times`` (N,) relative to the first record. At an
    inner waypoint where the path turns, the overshoot is the largest excursion of the true tip
    past the corner along the incoming edge direction within ``window`` seconds after the
    desired path reached it (zero if the tip never passes the corner).
    """
    if not records or len(waypoints) < 3:
        return np.zeros(0)
    t = np.array([r.t for r in records]) - records[0].t
    Q = np.array([r.p_true for r in records])
    out = []
    for i in range(1, len(waypoints) - 1):
        u = waypoints[i] - waypoints[i - 1]
        u = u / np.linalg.norm(u)
        sel = (t >= times[i]) & (t <= times[i] + window)
        if not np.any(sel):
            continue
        past = (Q[sel] - waypoints[i]) @ u
        out.append(max(0.0, float(past.max())))
    return np.asarray(out)
