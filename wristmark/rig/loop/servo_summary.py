"""The result JSON of a servo run: tip errors, capture-to-command latency, cycle timing, frames
and the link's counters.

Errors are the optical tracker's tip against the desired tip where a ground-truth observer ran
(the simulated bench); on hardware the only tip the host knows is its own vision estimate, so
the errors are the estimate against the desired tip (``errors_from`` says which).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.rig.loop.loop_setup import LoopSetup
from wristmark.rig.loop.metrics import (
    angle_stats_deg,
    error_stats,
    estimate_errors,
    orientation_errors,
    orientation_summary,
    tracking_errors,
)
from wristmark.rig.loop.servo_session import PointHold, ServoOutcome, ServoSession
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.rig.targets.trajectories import Trajectory

Array = NDArray[np.float64]


def percentiles_ms(values_ms: Array) -> dict[str, Any]:
    """Median, p95 and max of the finite values [ms], and their count."""
    v = np.asarray(values_ms, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"median_ms": None, "p95_ms": None, "max_ms": None, "n": 0}
    return {"median_ms": float(np.median(v)), "p95_ms": float(np.percentile(v, 95)), "max_ms": float(v.max()),
            "n": int(v.size)}


def cycle_timing(records: list[CycleRecord], dt: float) -> dict[str, Any]:
    """Cycle starts on the wall clock: period median and jitter (start minus its nominal time,
    the nominal schedule fitted as first start + k dt, k each record's cycle counted from its
    nominal time ``t``: a log with skipped cycles or another arm's probe between its own is not
    late by the gap) [ms]."""
    t_wall = np.array([r.t_wall for r in records], float)
    t_nom = np.array([r.t for r in records], float)
    ok = np.isfinite(t_wall) & np.isfinite(t_nom)
    t, t_nom = t_wall[ok], t_nom[ok]
    if t.size < 2:
        return {"period_median_ms": None, "jitter_ms": percentiles_ms(np.zeros(0))}
    k = np.round((t_nom - t_nom[0]) / dt)
    late = t - (t[0] + dt * k)
    late -= np.median(late)
    return {"period_median_ms": float(1000 * np.median(np.diff(t))),
            "jitter_ms": percentiles_ms(1000 * np.abs(late))}


def latency_summary(records: list[CycleRecord]) -> dict[str, Any]:
    """Capture -> command of the accepted measurements, split into the frame's transport
    (capture -> available to the loop) and what the host adds (available -> command), and the
    tracking time [ms]."""
    lat = np.array([r.latency_ms for r in records], float)
    transport = np.array([r.transport_ms if np.isfinite(r.latency_ms) else np.nan for r in records], float)
    return {"capture_to_command": percentiles_ms(lat), "transport": percentiles_ms(transport),
            "arrival_to_command": percentiles_ms(lat - transport),
            "tracking": percentiles_ms(np.array([r.vision_ms for r in records if r.vision_ms > 0]))}


def closed_loop_errors(records: list[CycleRecord]) -> dict[str, Any]:
    """Tip errors of the logged cycles [mm]: tracker vs desired (and noise-free truth) when
    there is ground truth, else the vision estimate vs desired."""
    trk = error_stats(tracking_errors(records, "p_trk"))
    if trk.n:
        true = error_stats(tracking_errors(records, "p_true"))
        out: dict[str, Any] = {**trk.as_dict(), "cycles": len(records), "errors_from": "optical tracker",
                               "noise_free": {"mean_mm": true.mean_mm, "max_mm": true.max_mm}}
        est = error_stats(estimate_errors(records))
        if est.n:
            out["vision_vs_true"] = {"mean_mm": est.mean_mm, "max_mm": est.max_mm}
        return out
    vis = error_stats(tracking_errors(records, "p_est"))
    return {**vis.as_dict(), "cycles": len(records), "errors_from": "vision estimate"}


def orientation_errors_of(traj: Trajectory, records: list[CycleRecord]) -> dict[str, Any]:
    """The orientation fields [deg] of a run whose path asks for an orientation (none otherwise):
    the optical tracker's against the desired where there is ground truth, else the vision
    estimate's (``orientation_from`` says which)."""
    if traj.orientation is None:
        return {}
    if any(r.R_trk is not None and bool(np.all(np.isfinite(r.R_trk))) for r in records):  # NaN: no tracker
        return {**orientation_summary(records), "orientation_from": "optical tracker"}
    vis = angle_stats_deg(orientation_errors(records, "R_est"))
    return {"orientation_mean_deg": vis["mean_deg"], "orientation_max_deg": vis["max_deg"],
            "orientation_from": "vision estimate"}


def summarize(setup: LoopSetup, traj: Trajectory, session: ServoSession, out: ServoOutcome) -> dict[str, Any]:
    """The result JSON of a run (see the module docstring)."""
    recs = out.log.phase("servo")
    closed = {**closed_loop_errors(recs), **orientation_errors_of(traj, recs), "lost": out.lost,
              "rejected": out.rejected, "no_frame": out.no_frame,
              "skipped": out.skipped, "dithers": out.dithers}
    if out.play_probe is not None:  # the play probe before the walk (rig/loop/play_probe.py), SI units
        closed["play_probe"] = out.play_probe
    closed["play_shrinks"] = out.play_shrinks  # plays shrunk for buzzing (solvers/play_observer.py)
    if out.motion_map is not None:  # measured tip motion ~ matrix @ the model's (rig/loop/motion_correction.py)
        closed["motion_map"] = out.motion_map
    link: dict[str, Any] = {"kind": session.options.kind, "port": session.port,
                            "realtime": session.options.realtime or session.options.kind in ("serial", "ros2")}
    driver = getattr(session.link, "driver", None)
    if driver is not None:
        link.update(driver.stats)
        if getattr(driver, "version", None) is not None:  # the protocol the device answered PING with
            link["protocol"] = {"version": driver.version, "actuators": driver.count}
        st = getattr(session.link, "state", None)
        if st is not None:
            link["device"] = {"flags": st.flags, "enabled": st.enabled, "estopped": st.estopped,
                              "watchdog_tripped": st.watchdog_tripped, "clock_ms": st.clock_ms}
        link.update(dataclasses.asdict(session.link.stats))  # type: ignore[attr-defined]
    all_recs = [r for r in out.log.records if r.phase.startswith("servo")]
    frames = {"source": session.camera or session.frames.name, "dropped": session.frames.dropped,
              "received": getattr(session.frames, "received", None), "wall_clock": session.wall_clock}
    kind = "point" if isinstance(traj, PointHold) else "cube"
    return {
        "command": "servo", "trajectory": {"kind": kind, "duration_s": traj.duration,
                                           "waypoints_m": np.asarray(traj.waypoints).tolist(),
                                           "orientation": traj.orientation_mode},
        "controller": setup.controller.kind, "control_dt_s": setup.rig.control_dt,
        "sensor": setup.rig.sensor if session.truth is not None else "vision (camera)",
        "closed_loop": closed,
        "latency": latency_summary(all_recs),
        "timing": cycle_timing(all_recs, setup.rig.control_dt),
        "frames": frames,
        "stopped": out.stopped, "cause": out.cause,
        "t_stop_s": out.t_stop if out.stopped else None,
        "safe_stop": {"held_and_disabled": not out.close_error, "problem": out.close_error},
        "link": link, "wall_time_s": out.wall_time_s,
    }
