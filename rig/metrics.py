"""Tracking-error metrics of a logged phase: errors, corner overshoot (reported in mm)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from rig.run_log import CycleRecord

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


def corner_overshoot(records: list[CycleRecord], window: float = 1.0) -> Array:
    """Overshoot at each direction change of the desired path [m].

    A corner is where the desired direction of motion turns by more than 45 deg. The overshoot
    is the largest excursion of the true tip past the corner along the incoming direction within
    ``window`` seconds after it (zero if it never passes the corner).
    """
    if len(records) < 3:
        return np.zeros(0)
    t = np.array([r.t for r in records])
    P = np.array([r.p_des for r in records])
    Q = np.array([r.p_true for r in records])
    d = np.diff(P, axis=0)
    n = np.linalg.norm(d, axis=1)
    moving = n > 1e-9
    out = []
    last_dir: Array | None = None
    for i in range(len(d)):
        if not moving[i]:
            continue
        u = d[i] / n[i]
        if last_dir is not None and float(u @ last_dir) < np.cos(np.radians(45)):
            corner = P[i]
            sel = (t >= t[i]) & (t <= t[i] + window)
            past = (Q[sel] - corner) @ last_dir
            out.append(max(0.0, float(past.max())) if past.size else 0.0)
        last_dir = u
    return np.asarray(out)
