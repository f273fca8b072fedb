"""The paper's experiments on the simulated bench (Sec. IV.B accuracy, IV.C cube) and the load
sweep of its future work. Each run writes a folder: config.json, log.csv, result.json,
results.md and PNG plots."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.models.arm_spec import as_spec, home_psi
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics
from wristmark.rig.loop.metrics import error_stats
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.recording.run_log import CycleRecord, RunLog, write_json
from wristmark.rig.targets.orientation_path import check_orientation_mode
from wristmark.rig.targets.trajectories import (
    CUBE_SIZE,
    CUBE_SPEED,
    Trajectory,
    accuracy_targets,
    cube_trajectory,
    workspace_centre,
)
from wristmark.sim.setup import SimSetup, make_measurement, make_plant
from wristmark.sim.trajectory_run import check_reach, walk_trajectory

PAPER_CUBE = {"open_loop": {"mean_mm": 3.25, "max_mm": 8.40},
              "closed_loop": {"mean_mm": 0.82, "max_mm": 2.59}, "ratio": 0.2523}
PAPER_ACCURACY = {"mean_mm": 0.67, "max_mm": 1.21}


def run_cube(setup: SimSetup, out_dir: Path, progress: bool = True, seed: int | None = None,
             duration: float | None = None, on_cycle: Callable[[CycleRecord], None] | None = None,
             on_frame: Callable[..., None] | None = None, orientation: str = "none") -> dict[str, Any]:
    """Cube trajectory open loop then closed loop on fresh plants; writes the run folder.

    ``duration`` [s] cuts the walk short (quick checks); None runs all 12 edges. ``on_cycle`` is
    called with every cycle's record, ``on_frame`` with every measured frame and its
    measurement (e.g. a live 3D view). ``orientation``: none | hold | follow (rig/targets/orientation_path.py)."""
    traj = cube_trajectory(workspace_centre(setup.params), CUBE_SIZE, CUBE_SPEED)
    if duration is not None:
        traj = traj.truncated(duration)
    return run_open_closed(setup, traj.with_orientation(check_orientation(setup, orientation), setup.params), "cube",
                           out_dir, progress, seed, on_cycle, on_frame)


def check_orientation(setup: SimSetup, orientation: str) -> str:
    """``orientation`` if the setup's controller can control it (ConfigError otherwise: the paper's
    controller is position-only, as the paper defines it)."""
    return check_orientation_mode(orientation, setup.controller.kind)


def run_point(setup: SimSetup, out_dir: Path, point: np.ndarray | None = None, progress: bool = True,
              seed: int | None = None, duration: float | None = None,
              on_cycle: Callable[[CycleRecord], None] | None = None,
              on_frame: Callable[..., None] | None = None, orientation: str = "none") -> dict[str, Any]:
    """Hold ``point`` in {w} [m] (default: the workspace centre) for ``duration`` [s] (default
    POINT_HOLD_S), open loop then closed loop on fresh plants; writes the run folder.
    ``orientation``: none | hold | follow (both hold the start's orientation on a point)."""
    from wristmark.rig.loop.servo_session import POINT_HOLD_S, PointHold

    p = workspace_centre(setup.params) if point is None else np.asarray(point, float)
    check_reach(setup, np.array([p]))
    traj = PointHold(np.array([p]), 1.0, hold=POINT_HOLD_S if duration is None else duration)
    traj = traj.with_orientation(check_orientation(setup, orientation), setup.params)
    return run_open_closed(setup, traj, "point", out_dir, progress, seed, on_cycle, on_frame)


def run_open_closed(setup: SimSetup, traj: Trajectory, experiment: str, out_dir: Path, progress: bool = True,
                    seed: int | None = None,
                    on_cycle: Callable[[CycleRecord], None] | None = None,
                    on_frame: Callable[..., None] | None = None) -> dict[str, Any]:
    """Follow ``traj`` open loop then closed loop on fresh plants (sim.trajectory_run, one log);
    writes the run folder."""
    from wristmark.viz.plots import plot_cube

    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / "config.json", {"experiment": experiment, **setup.describe()})
    centre = workspace_centre(setup.params)
    log = RunLog.for_arm(setup.params)
    walks = {phase: walk_trajectory(setup, traj, phase == "closed_loop", log, phase, seed=seed, progress=progress,
                                    on_cycle=on_cycle, on_frame=on_frame) for phase in ("open_loop", "closed_loop")}
    stats = {phase: w.stats for phase, w in walks.items()}
    log.write_csv(out_dir / "log.csv")
    res: dict[str, Any] = {
        "experiment": experiment,
        "controller": setup.controller.kind,
        "control_dt_s": setup.rig.control_dt,
        "sensor": setup.rig.sensor,
        "orientation": traj.orientation_mode,
        "open_loop": walks["open_loop"].summary,
        "closed_loop": walks["closed_loop"].summary,
        "paper": PAPER_CUBE,
        "trajectory": {"size_m": list(CUBE_SIZE), "speed_m_s": CUBE_SPEED, "duration_s": traj.duration,
                       "centre_world_m": centre.tolist()} if experiment == "cube" else
                      {"point_world_m": traj.waypoints[0].tolist(), "duration_s": traj.duration},
        "run_dir": str(out_dir),
    }
    res["ratio"] = res["closed_loop"]["mean_mm"] / res["open_loop"]["mean_mm"]
    if log.psi_names is not None:  # any arm but the reference arm's flat file: which arm, by its names
        spec = as_spec(setup.params)
        res["arm"] = {"name": spec.name, "configuration": list(spec.names), "actuators": list(spec.actuator_names)}
    for k, s in stats.items():
        res[k]["lost"] = s.lost
        res[k]["rejected"] = s.rejected
        res[k]["dithers"] = s.dithers
        res[k]["stopped"] = s.stopped
        if s.open_on_lost:  # rig open_loop_on_lost: the cycles walked open loop while the marker was lost
            res[k]["open_on_lost"] = s.open_on_lost
    write_json(out_dir / "result.json", res)
    (out_dir / "results.md").write_text(cube_table(res))
    plot_cube(log, out_dir)
    return res


def cube_table(res: dict[str, Any]) -> str:
    """Markdown table of a cube result beside the paper's numbers."""
    o, c, p = res["open_loop"], res["closed_loop"], res["paper"]
    title = "Point hold" if res.get("experiment") == "point" else "Cube trajectory"
    lines = [
        f"# {title}: open vs closed loop (controller `{res['controller']}`, "
        f"cycle {1000 * res['control_dt_s']:.0f} ms, sensor {res['sensor']})",
        "",
        "| | open-loop mean [mm] | open-loop max [mm] | closed-loop mean [mm] | closed-loop max [mm] | closed/open |",
        "|---|---|---|---|---|---|",
        f"| paper (Fig. 8) | {p['open_loop']['mean_mm']:.2f} | {p['open_loop']['max_mm']:.2f} | "
        f"{p['closed_loop']['mean_mm']:.2f} | {p['closed_loop']['max_mm']:.2f} | {100 * p['ratio']:.2f} % |",
        f"| wristmark (simulated bench) | {o['mean_mm']:.2f} | {o['max_mm']:.2f} | {c['mean_mm']:.2f} | "
        f"{c['max_mm']:.2f} | {100 * res['ratio']:.2f} % |",
        "",
        f"Corner overshoot (closed loop): max {c['corner_overshoot_mm']['max']:.2f} mm over "
        f"{c['corner_overshoot_mm']['corners']} corners. Errors: optical-tracker tip vs desired tip over "
        f"{o['cycles']} open-loop and {c['cycles']} closed-loop cycles of the trajectory (the settling "
        "cycles before each are not counted).",
        "",
    ]
    if c.get("orientation_mean_deg") is not None:
        lines += [f"Orientation ({res.get('orientation')}: angle between the optical tracker's and the desired tip "
                  f"frame): open loop mean {o['orientation_mean_deg']:.2f} deg, "
                  f"max {o['orientation_max_deg']:.2f} deg; "
                  f"closed loop mean {c['orientation_mean_deg']:.2f} deg, max {c['orientation_max_deg']:.2f} deg "
                  f"(z axis alone: closed loop mean {c['axis_mean_deg']:.2f} deg, max {c['axis_max_deg']:.2f} deg).",
                  ""]
    if c.get("stopped"):
        lines += [f"**The closed loop stopped safely: {c['stopped']}** (statistics cover the cycles before).", ""]
    return "\n".join(lines)


def run_accuracy(setup: SimSetup, out_dir: Path, n: int = 40, progress: bool = True,
                 seed: int | None = None) -> dict[str, Any]:
    """Paper IV.B: n positions reached by incremental moves; stereo estimate vs tracker."""
    from tqdm import tqdm

    from wristmark.models.actuation import actuators_from_psi
    from wristmark.sim.optical_tracker import OpticalTracker
    from wristmark.viz.plots import plot_accuracy

    seed = setup.rig.seed if seed is None else seed
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / "config.json", {"experiment": "accuracy", **setup.describe()})
    targets = accuracy_targets(workspace_centre(setup.params), n=n, seed=seed)
    psi = home_psi(setup.params)
    plant = make_plant(setup, psi)
    frames, sensor = make_measurement(setup, plant, lambda: plant.time, seed)
    tracker = OpticalTracker(setup.rig.tracker_rms, seed=seed + 7)
    rows = []
    for i, p in enumerate(tqdm(targets, desc="accuracy", disable=not progress, leave=False)):
        psi = solve_tip_ik(setup.params, p, psi).psi
        plant.command(actuators_from_psi(setup.params, psi))
        plant.advance(1.0)
        shape = plant.true_shape()
        p_trk = tracker.measure(shape.tip)
        frame = frames.take()
        assert frame is not None
        m = sensor.measure(frame, axis_hint_world=forward_kinematics(setup.params, psi).T_world_marker[:3, 2])
        err = float(np.linalg.norm(m.p_world - p_trk)) if m.ok and m.p_world is not None else float("nan")
        rows.append({"index": i, "target": p.tolist(), "tracker": p_trk.tolist(), "true": shape.tip.tolist(),
                     "estimate": None if m.p_world is None else m.p_world.tolist(), "ok": m.ok,
                     "reason": m.reason, "error_mm": 1000 * err, "rms_px": m.rms_px,
                     "tip_sigma_mm": 1000 * m.tip_sigma_m if np.isfinite(m.tip_sigma_m) else None})
    errs = np.array([r["error_mm"] for r in rows]) / 1000.0
    st = error_stats(errs)
    true_errs = np.array([np.linalg.norm(np.subtract(r["estimate"], r["true"])) if r["ok"] else np.nan
                          for r in rows])
    res = {"experiment": "accuracy", "mean_mm": st.mean_mm, "max_mm": st.max_mm, "rms_mm": st.rms_mm,
           "tracked": int(sum(r["ok"] for r in rows)), "positions": n,
           "vs_noise_free_truth": error_stats(true_errs).as_dict(), "paper": PAPER_ACCURACY,
           "sensor": setup.rig.sensor, "positions_detail": rows, "run_dir": str(out_dir)}
    write_json(out_dir / "result.json", res)
    plot_accuracy(rows, out_dir)
    return res


def run_load(setup: SimSetup, out_dir: Path, forces: list[float], progress: bool = True,
             duration: float | None = None, on_cycle: Callable[[CycleRecord], None] | None = None,
             on_frame: Callable[..., None] | None = None, orientation: str = "none") -> dict[str, Any]:
    """Tip force swept (magnitude [N], direction -z_w, gravity-like): cube open vs closed loop
    (``orientation`` as in run_cube)."""
    from tqdm import tqdm

    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    res: dict[str, Any] = {}
    sweep = tqdm(forces, unit="force", disable=not progress)  # the phases' bars run below it
    for i, f in enumerate(sweep):
        sweep.set_description(f"load: force {i + 1} of {len(forces)} ({f:.2f} N)")
        plant = dataclasses.replace(setup.plant, tip_force=(0.0, 0.0, -float(f)))
        res = run_cube(setup.with_changes(plant=plant), out_dir / f"force_{f:.2f}N", progress=progress,
                       duration=duration, on_cycle=on_cycle, on_frame=on_frame, orientation=orientation)
        rows.append({"force_N": f, "open_loop": {k: res["open_loop"][k] for k in ("mean_mm", "max_mm")},
                     "closed_loop": {k: res["closed_loop"][k] for k in ("mean_mm", "max_mm", "stopped")},
                     "ratio": res["ratio"]})
    sweep.close()
    out = {"experiment": "load", "controller": setup.controller.kind, "control_dt_s": setup.rig.control_dt,
           "duration_s": res.get("trajectory", {}).get("duration_s"), "rows": rows, "run_dir": str(out_dir)}
    write_json(out_dir / "result.json", out)
    md = ["# Tip load sweep: cube trajectory open vs closed loop", "",
          "| tip force [N] | open mean [mm] | open max [mm] | closed mean [mm] | closed max [mm] | ratio |",
          "|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['force_N']:.2f} | {r['open_loop']['mean_mm']:.2f} | {r['open_loop']['max_mm']:.2f} | "
                  f"{r['closed_loop']['mean_mm']:.2f} | {r['closed_loop']['max_mm']:.2f} | {100 * r['ratio']:.1f} % |")
    (out_dir / "results.md").write_text("\n".join(md) + "\n")
    return out


__all__ = ["CUBE_SIZE", "CUBE_SPEED", "run_cube", "run_point", "run_open_closed", "run_accuracy", "run_load",
           "ServoLoop"]
