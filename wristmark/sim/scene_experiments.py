"""The cube experiment with several arms in one view (``wristmark experiment cube --scene``).

Each arm walks its own cube (the scene's ``cube_size`` around its workspace centre, in its own
{w}, at the paper's speed), open loop then closed loop, all arms at once (sim.several_arms);
arms named in ``hold`` hold their workspace centre for as long instead. The run folder has
config.json, result.json (per arm the one-arm experiment's fields, and the clearance), results.md
and log_<arm>.csv per arm.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.rig.loop.arm_set_session import arm_trajectories, check_arm_orientation
from wristmark.rig.recording.run_log import CycleRecord, RunLog, write_json
from wristmark.rig.targets.trajectories import Trajectory, workspace_centre
from wristmark.sim.scene_setup import SceneSetup
from wristmark.sim.several_arms import walk_scene

__all__ = ["run_scene_cube", "scene_table"]


def scene_trajectories(setup: SceneSetup, duration: float | None = None,
                       hold: tuple[str, ...] = (), orientation: str = "none") -> dict[str, Trajectory]:
    """Each arm's cube (or, for the arms in ``hold``, its workspace centre held as long as the
    cubes take), in its own {w}; ``duration`` [s] cuts the walks short; ``orientation`` (none |
    hold | follow) the tip frame's orientation each path asks for (ConfigError when an arm's
    controller is position-only; rig.loop.arm_set_session.arm_trajectories, shared with the
    hardware path)."""
    check_arm_orientation(orientation, {n: s.controller.kind for n, s in setup.arms.items()})
    return arm_trajectories({n: s.params for n, s in setup.arms.items()}, setup.scene.cube_size, "cube", duration,
                            hold, orientation)


def run_scene_cube(setup: SceneSetup, out_dir: Path, duration: float | None = None,
                   hold: tuple[str, ...] = (), seed: int | None = None,
                   on_cycle: Callable[[str, CycleRecord], None] | None = None,
                   orientation: str = "none", processes: bool = False) -> dict[str, Any]:
    """Every arm's cube, open loop then closed loop on fresh arms, all at once; writes the run
    folder. ``on_cycle(arm, record)`` is called after every cycle of every arm (a live view's);
    ``orientation`` (none | hold | follow): the tip frame's orientation every arm's path asks for
    (its errors in result.json, as the one-arm experiment's); ``processes``: the closed loop's
    tracker runs every arm but the first in a worker process of its own (the same results)."""
    trajs = scene_trajectories(setup, duration, hold, orientation)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / "config.json", {"experiment": "cube", **setup.describe()})
    logs = {n: RunLog.for_arm(s.params) for n, s in setup.arms.items()}
    walks = {phase: walk_scene(setup, trajs, phase == "closed_loop", phase, logs=logs, seed=seed, on_cycle=on_cycle,
                               processes=processes)
             for phase in ("open_loop", "closed_loop")}
    rig = next(iter(setup.arms.values())).rig
    arms: dict[str, Any] = {}
    for n in setup.names:
        logs[n].write_csv(out_dir / f"log_{n}.csv")
        res: dict[str, Any] = {"walk": "hold" if n in hold else "cube"}
        for phase, w in walks.items():
            a = w.arms[n]
            res[phase] = {**a.summary, "lost": a.stats.lost, "rejected": a.stats.rejected, "stopped": a.stopped}
        res["ratio"] = res["closed_loop"]["mean_mm"] / res["open_loop"]["mean_mm"] if res["open_loop"]["mean_mm"] \
            else float("nan")
        res["trajectory"] = {"duration_s": trajs[n].duration, "centre_world_m": trajs[n].waypoints[0].tolist()
                             if n in hold else workspace_centre(setup.arms[n].params, setup.scene.cube_size).tolist()}
        arms[n] = res
    closed = walks["closed_loop"]
    result: dict[str, Any] = {
        "experiment": "cube",
        "scene": setup.scene.source,
        "controller": next(iter(setup.arms.values())).controller.kind,
        "orientation": orientation,
        "control_dt_s": rig.control_dt,
        "sensor": rig.sensor,
        "cube_size_m": list(setup.scene.cube_size),
        "arms": arms,
        "clearance": {
            "required_mm": 1000 * setup.scene.clearance,
            "least_true_mm": {p: 1000 * w.least_distance_m for p, w in walks.items()},
            # the constraint acts in the closed loop; the open-loop baseline commands the nominal IK alone
            "kept": bool(walks["closed_loop"].least_distance_m >= setup.scene.clearance),
        },
        "tracking_ms_median": float(np.median(closed.tracking_ms)) if closed.tracking_ms else float("nan"),
        "run_dir": str(out_dir),
    }
    write_json(out_dir / "result.json", result)
    (out_dir / "results.md").write_text(scene_table(result))
    return result


def scene_table(res: dict[str, Any]) -> str:
    """Markdown table of a scene cube result: per arm open and closed loop."""
    lines = [f"# Cube trajectory with {len(res['arms'])} arms in one view (controller `{res['controller']}`, "
             f"cycle {1000 * res['control_dt_s']:.0f} ms, sensor {res['sensor']})", "",
             "| arm | walk | open-loop mean [mm] | open-loop max [mm] | closed-loop mean [mm] | closed-loop max [mm] "
             "| closed/open | lost | stopped |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n, a in res["arms"].items():
        o, c = a["open_loop"], a["closed_loop"]
        lines.append(f"| {n} | {a['walk']} | {o['mean_mm']:.2f} | {o['max_mm']:.2f} | {c['mean_mm']:.3f} | "
                     f"{c['max_mm']:.3f} | {100 * a['ratio']:.1f} % | {c['lost']} | {c['stopped'] or '-'} |")
    if res.get("orientation", "none") != "none":
        lines += ["", f"Orientation ({res['orientation']}), tip frame vs desired, closed loop: " + "; ".join(
            f"{n} mean {a['closed_loop']['orientation_mean_deg']:.2f} deg, max "
            f"{a['closed_loop']['orientation_max_deg']:.2f} deg" for n, a in res["arms"].items()) + "."]
    cl = res["clearance"]
    lines += ["", f"Least distance between the arms' true bodies: {cl['least_true_mm']['closed_loop']:.1f} mm closed "
              f"loop (clearance {cl['required_mm']:.1f} mm: {'kept' if cl['kept'] else 'VIOLATED'}), "
              f"{cl['least_true_mm']['open_loop']:.1f} mm open loop (no constraint). Tracking all sleeves: median "
              f"{res['tracking_ms_median']:.1f} ms per frame.", ""]
    return "\n".join(lines)
