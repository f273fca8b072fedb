"""Walk any trajectory on the simulated bench from Python, in process: the loop of the paper's
experiments (a fresh true arm, the rendered stereo frames tracked by the marker tracker, the
controller) without a run folder or the command line.

    setup = load_setup()
    path = Trajectory.from_waypoints(points_world, speed=0.01)   # {w} [m], [m/s]
    run = run_trajectory(setup, path)                            # closed loop, vision in the loop
    print(run.errors.mean_mm, run.errors.max_mm)

Call ``wristmark.warm_up()`` once first when wall time matters (the results do not depend on it:
the bench runs in simulated time). The experiments (sim.experiments) walk their paths through
the same function.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from wristmark.models.arm_spec import home_psi
from wristmark.models.errors import ConfigError
from wristmark.models.ik import solve_tip_ik
from wristmark.rig.loop.metrics import (
    ErrorStats,
    corner_overshoot,
    error_stats,
    estimate_errors,
    orientation_summary,
    tracking_errors,
)
from wristmark.rig.loop.play_probe import probe_report
from wristmark.rig.loop.servo_loop import MarkerLostError, PhaseStats
from wristmark.rig.recording.run_log import CycleRecord, RunLog
from wristmark.rig.targets.orientation_path import start_configuration
from wristmark.rig.targets.trajectories import Trajectory
from wristmark.sim.setup import SimSetup, make_direct_loop

REACH_TOLERANCE = 1e-4  # [m] a waypoint the position IK misses by more is out of reach


@dataclass(frozen=True)
class TrajectoryRun:
    """One walk of a trajectory on the simulated bench. ``log``: every cycle ({w} [m], [s]; the
    settle cycles under ``phase + ':settle'``); ``errors``: the optical tracker's tip against the
    desired tip over the walk's cycles [mm] (what the paper reports), ``true_errors`` the same for
    the noise-free true tip; ``summary``: the experiments' result.json fields of the phase;
    ``stopped``: why the loop stopped safely ("" when the walk completed)."""

    phase: str
    closed_loop: bool
    log: RunLog
    stats: PhaseStats
    errors: ErrorStats
    true_errors: ErrorStats
    summary: dict[str, Any]
    stopped: str = ""

    @property
    def records(self) -> list[CycleRecord]:
        """The walk's cycles (settling excluded)."""
        return self.log.phase(self.phase)


def phase_summary(log: RunLog, phase: str, traj: Trajectory) -> dict[str, Any]:
    """The result.json fields of one logged phase: tip errors [mm] (optical tracker and noise-free
    truth vs desired), corner overshoot [mm], orientation errors [deg] when the path asks for
    one, and, closed loop, the vision estimate vs truth [mm] and the measurements' counts."""
    recs = log.phase(phase)
    trk = error_stats(tracking_errors(recs, "p_trk"))
    true = error_stats(tracking_errors(recs, "p_true"))
    over = corner_overshoot(recs, traj.waypoints, traj.times)
    out: dict[str, Any] = {
        "mean_mm": trk.mean_mm, "max_mm": trk.max_mm, "rms_mm": trk.rms_mm, "p95_mm": trk.p95_mm,
        "cycles": trk.n,
        "noise_free": {"mean_mm": true.mean_mm, "max_mm": true.max_mm},
        "corner_overshoot_mm": {
            "max": float(1000 * over.max()) if over.size else 0.0,
            "mean": float(1000 * over.mean()) if over.size else 0.0,
            "corners": int(over.size),
        },
    }
    if traj.orientation is not None:
        out.update(orientation_summary(recs))
    est = error_stats(estimate_errors(recs))
    if est.n:
        out["vision_vs_true"] = {"mean_mm": est.mean_mm, "max_mm": est.max_mm}
        ok = [r for r in recs if r.meas_ok]
        out["measurements"] = {"accepted": len(ok), "lost_or_rejected": len(recs) - len(ok)}
        out["vision_ms_median"] = float(np.median([r.vision_ms for r in recs if r.vision_ms > 0] or [0]))
        out["ctrl_us_median"] = float(np.median([r.ctrl_us for r in ok] or [0]))
    return out


def check_reach(setup: SimSetup, points_world: np.ndarray) -> None:
    """ConfigError (one line, in mm) naming the first point (n, 3) in {w} [m] the arm cannot reach."""
    psi = home_psi(setup.params)
    for i, p in enumerate(np.asarray(points_world, float).reshape(-1, 3)):
        ik = solve_tip_ik(setup.params, p, psi)
        if not ik.error <= REACH_TOLERANCE:
            which = "the point" if len(points_world) == 1 else f"waypoint {i},"
            raise ConfigError(f"{which} {np.round(1000 * p, 2).tolist()} mm is out of reach of the arm "
                              f"(IK misses it by {1000 * ik.error:.2f} mm)")
        psi = ik.psi


def run_trajectory(setup: SimSetup, trajectory: Trajectory, closed_loop: bool = True, seed: int | None = None,
                   progress: bool = False, on_cycle: Callable[[CycleRecord], None] | None = None,
                   on_frame: Callable[..., None] | None = None) -> TrajectoryRun:
    """Walk ``trajectory`` (waypoints in {w} [m]) once on a fresh simulated arm, in process, after
    ``setup.rig.settle_time`` [s] at its start: closed loop on the tip the rig's sensor measures
    (``sensor: vision``: the marker tracked in rendered frames) or open loop (commands from the
    model alone). ``seed`` (default the rig's) seeds the frames' noise and the optical tracker;
    ``on_cycle`` sees every cycle's record, ``on_frame(frame, measurement)`` every measured frame.
    A safe stop (marker lost, camera stalled) is reported in ``stopped``, not raised; a waypoint
    out of reach is a ConfigError before anything runs. Writes nothing to disk."""
    check_reach(setup, trajectory.waypoints)
    log = RunLog.for_arm(setup.params)
    return walk_trajectory(setup, trajectory, closed_loop, log, seed=seed, progress=progress,
                           on_cycle=on_cycle, on_frame=on_frame)


def walk_trajectory(setup: SimSetup, trajectory: Trajectory, closed_loop: bool, log: RunLog, phase: str | None = None,
                    seed: int | None = None, progress: bool = False,
                    on_cycle: Callable[[CycleRecord], None] | None = None,
                    on_frame: Callable[..., None] | None = None) -> TrajectoryRun:
    """:func:`run_trajectory` without the reach check, logging into ``log`` under ``phase``
    (default closed_loop | open_loop): the experiments walk both phases into one log."""
    seed = setup.rig.seed if seed is None else int(seed)
    phase = phase or ("closed_loop" if closed_loop else "open_loop")
    loop = make_direct_loop(setup, start_configuration(setup.params, trajectory.sample(0.0)[0]),
                            closed_loop=closed_loop, seed=seed)
    loop.on_cycle = on_cycle
    if closed_loop:
        loop.on_frame = on_frame
    stopped = ""
    try:
        stats = loop.run(trajectory, phase, closed_loop, log, settle=setup.rig.settle_time, progress=progress)
    except MarkerLostError as e:  # a safe stop is a result too: report what ran up to it
        stats = e.stats if e.stats is not None else PhaseStats(stopped=str(e))
        stopped = stats.stopped or str(e)
    summary = phase_summary(log, phase, trajectory)
    probe = probe_report(loop.play_fits, loop.play_probe_note) if closed_loop else None
    if probe is not None:  # the play probe (rig/loop/play_probe.py)
        summary["play_probe"] = probe
    if closed_loop and loop.controller is not None:  # plays shrunk for buzzing (solvers/play_observer.py)
        summary["play_shrinks"] = loop.controller.play_shrinks
    if closed_loop and loop.controller is not None and loop.controller.compensation_note:
        summary["backlash_inversion"] = loop.controller.compensation_note
    recs = log.phase(phase)
    return TrajectoryRun(phase, closed_loop, log, stats, error_stats(tracking_errors(recs, "p_trk")),
                         error_stats(tracking_errors(recs, "p_true")), summary, stopped)
