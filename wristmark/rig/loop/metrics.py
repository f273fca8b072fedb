"""Tracking-error metrics of a logged phase: errors, corner overshoot (reported in mm), and the
tip frame's orientation errors (reported in deg)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.so3 import axis_angle_between
from wristmark.rig.recording.run_log import CycleRecord

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


def orientation_errors(records: list[CycleRecord], which: str = "R_trk") -> Array:
    """Angle between the orientation ``which`` (R_trk tracker, R_true noise-free, R_est vision)
    and the desired one per record [rad] (nan where either is unknown)."""
    return np.asarray([r.orientation_error(which) for r in records])


def axis_errors(records: list[CycleRecord], which: str = "R_trk") -> Array:
    """Angle between the tip frame's z axis of ``which`` and the desired one per record [rad]
    (what a reference sleeve, roll unknown, can hold); nan where either is unknown."""
    out = []
    for r in records:
        R = getattr(r, which)
        ok = r.R_des is not None and R is not None and bool(np.all(np.isfinite(R)))
        out.append(axis_angle_between(np.asarray(r.R_des)[:, 2], np.asarray(R)[:, 2]) if ok else np.nan)
    return np.asarray(out)


def angle_stats_deg(errors_rad: Array) -> dict[str, float]:
    """Mean and max [deg] of the finite angles [rad] (NaN when there are none)."""
    e = np.rad2deg(np.asarray(errors_rad, float))
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {"mean_deg": float("nan"), "max_deg": float("nan")}
    return {"mean_deg": float(e.mean()), "max_deg": float(e.max())}


def orientation_summary(records: list[CycleRecord]) -> dict[str, float]:
    """The result JSON's orientation fields of a phase [deg] (docs/design.md names):
    orientation_mean_deg / orientation_max_deg (tracker vs desired), the same noise-free
    (orientation_true_*) and for the z axis alone (axis_*)."""
    trk, true, axis = (angle_stats_deg(orientation_errors(records, "R_trk")),
                       angle_stats_deg(orientation_errors(records, "R_true")),
                       angle_stats_deg(axis_errors(records, "R_trk")))
    return {"orientation_mean_deg": trk["mean_deg"], "orientation_max_deg": trk["max_deg"],
            "orientation_true_mean_deg": true["mean_deg"], "orientation_true_max_deg": true["max_deg"],
            "axis_mean_deg": axis["mean_deg"], "axis_max_deg": axis["max_deg"]}


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
