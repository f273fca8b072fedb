"""``wristmark experiment {cube,point,accuracy,load}``: the paper's experiments on the simulated bench."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from wristmark.cli.common_options import JSON_FILE_HELP, add_force_argument, add_host_argument, set_example
from wristmark.cli.option_types import (
    MAX_DURATION_S,
    MAX_POSITIONS,
    MAX_TIP_FORCE_N,
    finite_float,
    int_in,
    nonnegative_float,
    positive_float,
)
from wristmark.cli.setup_args import (
    add_model_arguments,
    add_registration_argument,
    add_setup_arguments,
    setup_from_args,
)
from wristmark.cvs.tracking.warmup import warm_up
from wristmark.models.errors import ConfigError
from wristmark.rig.recording.output_dir import claim_outputs, link_latest, new_run_dir
from wristmark.rig.recording.run_log import write_json
from wristmark.rig.targets.orientation_path import ORIENTATION_MODES

if TYPE_CHECKING:
    from wristmark.rig.recording.run_log import CycleRecord
    from wristmark.sim.setup import SimSetup


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", choices=("cube", "point", "accuracy", "load"), help="which experiment")
    p.add_argument("--json", metavar="FILE.json", help=JSON_FILE_HELP.format(what="the result"))
    p.add_argument("--out", metavar="DIR",
                   help="output folder: the run folder, empty unless --force (default: a new runs/<name>-<time>, "
                        "linked as runs/latest)")
    set_example(p, "wristmark experiment cube --json runs/tour/cube.json",
                "wristmark experiment cube --plant configs/plant_misplaced_camera.yaml --registration reg.yaml",
                "wristmark experiment cube --scene configs/scenes/two_arms.yaml --duration 10")
    add_force_argument(p)
    add_setup_arguments(p)
    add_registration_argument(p)
    add_model_arguments(p)
    p.add_argument("--duration", type=positive_float(MAX_DURATION_S), metavar="S",
                   help="cube/load: run only the first S seconds of the cube walk (quick checks); "
                        "point: hold for S seconds (default 5)")
    p.add_argument("--point", type=finite_float(), nargs=3, metavar=("X", "Y", "Z"),
                   help="point: the point to hold in {w} [m] (default: the workspace centre)")
    p.add_argument("--positions", type=int_in(1, MAX_POSITIONS), default=40, help="accuracy: number of positions")
    p.add_argument("--forces", type=nonnegative_float(MAX_TIP_FORCE_N), nargs="+", default=[0.0, 0.1, 0.2, 0.3],
                   help="load: tip forces [N] to sweep")
    p.add_argument("--orientation", choices=ORIENTATION_MODES, default="none",
                   help="cube/point/load: the tip frame's orientation: none (position only, as the paper), hold "
                        "(the start's), follow (the nominal model's along the path); needs --controller qp")
    p.add_argument("--scene", metavar="SCENE.yaml",
                   help="cube: several arms in one view, each walking its own cube in its own loop on one camera "
                        "(a scene file: docs/formats.md; e.g. configs/scenes/two_arms.yaml)")
    p.add_argument("--hold", metavar="ARM", action="append",
                   help="with --scene: this arm holds its workspace centre while the others walk (repeatable)")
    p.add_argument("--arm-processes", action="store_true",
                   help="with --scene: track every arm but the first in a worker process of its own (the same results; "
                        "faster only with a core to spare, e.g. on hardware, not beside a virtual lab; ~2 s to start)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--view", action="store_true",
                   help="live 3D view in the browser (Meshcat; prints the URL to open); with --scene every arm")
    add_host_argument(p)


def check_args(args: argparse.Namespace) -> SimSetup:
    """Validate the options (ConfigError naming the bad one) and load the setup they ask for."""
    if args.duration is not None and not args.duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {args.duration}")
    if len({f"{f:.2f}" for f in args.forces}) != len(args.forces):
        raise ConfigError(f"--forces must differ by 0.01 N at least (each writes force_X.XXN/), got {args.forces}")
    if args.point is not None and args.name != "point":
        raise ConfigError("--point needs the point experiment")
    if args.orientation != "none" and args.name == "accuracy":
        raise ConfigError("--orientation needs the cube, point or load experiment")
    setup = setup_from_args(args)
    from wristmark.sim.experiments import check_orientation

    check_orientation(setup, args.orientation)
    return setup


def check_scene_args(args: argparse.Namespace) -> Any:
    """``--scene``: the options it allows, and the scene's setup (ConfigError / InputError naming the cause)."""
    from wristmark.cli.setup_args import scene_setup_from_args

    if args.name != "cube":
        raise ConfigError("--scene needs the cube experiment")
    if args.duration is not None and not args.duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {args.duration}")
    setup = scene_setup_from_args(args)
    from wristmark.sim.scene_experiments import scene_trajectories

    scene_trajectories(setup, args.duration, tuple(args.hold or ()), args.orientation)  # --hold names arms of the scene
    return setup


def run_scene(args: argparse.Namespace) -> int:
    """``experiment cube --scene``: every arm's loop on one camera; exit 3 if any arm stopped."""
    from wristmark.sim.scene_experiments import run_scene_cube

    setup = check_scene_args(args)
    out = Path(args.out) if args.out else new_run_dir("runs", "scene-cube")
    claim_outputs(dirs=[out], files=[args.json], force=args.force)
    warm_up()
    t0 = time.perf_counter()
    view = None
    if args.view:
        from wristmark.viz.live import start_scene_live_view

        view = start_scene_live_view(setup, host=args.host, stream=sys.stderr)
        print(f"the live view closes when the run ends; then replay the run: wristmark view {out}",
              file=sys.stderr, flush=True)
    try:
        res = run_scene_cube(setup, out, duration=args.duration, hold=tuple(args.hold or ()),
                             on_cycle=None if view is None else view.on_arm_cycle, orientation=args.orientation,
                             processes=args.arm_processes)
    finally:
        if view is not None:
            _close_view(view, out)
    print((out / "results.md").read_text())
    stopped = [f"arm {n}: {a['closed_loop']['stopped']}" for n, a in res["arms"].items() if a["closed_loop"]["stopped"]]
    return _finish(args, out, res, time.perf_counter() - t0, stopped)


def _close_view(view: Any, out: Path) -> None:
    """Close a live view after the run and say how to replay it (its URL is dead now)."""
    view.close()
    print(f"replay in the browser: wristmark view {out}", file=sys.stderr)
    print(f"(the live view at {view.url} has closed with the run)", file=sys.stderr)


def _finish(args: argparse.Namespace, out: Path, res: dict[str, Any], wall_s: float, stopped: list[str]) -> int:
    """Write ``--json``, name the run folder (linked as runs/latest without ``--out``) and the
    first safe stop; the exit code (3 after a safe stop)."""
    res["wall_time_s"] = wall_s
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, res)
    print(f"run folder: {out}")
    if not args.out:
        link_latest(out)
    if stopped:
        print(f"wristmark experiment: error: closed loop stopped safely: {stopped[0]}", file=sys.stderr)
        return 3
    return 0


def run(args: argparse.Namespace) -> int:
    if args.scene is not None:
        return run_scene(args)
    if args.hold:
        raise ConfigError("--hold needs --scene")
    if args.arm_processes:
        raise ConfigError("--arm-processes needs --scene")
    setup = check_args(args)
    out = Path(args.out) if args.out else new_run_dir("runs", args.name)
    claim_outputs(dirs=[out], files=[args.json], force=args.force)
    # OpenCV's threads and, for the vision sensor, the tracker's kernels before the first frame
    warm_up(jit=setup.rig.sensor == "vision")  # (cvs.tracking.warmup)
    progress = not args.no_progress
    t0 = time.perf_counter()
    view = None
    if args.view:
        from wristmark.viz.live import start_live_view

        view = start_live_view(setup, host=args.host)
        print(f"the live view closes when the run ends; then replay the run: wristmark view {out}",
              file=sys.stderr, flush=True)
    on_cycle = view.on_cycle if view is not None else None
    on_frame = view.on_frame if view is not None else None
    try:
        res = _run(args, setup, out, progress, on_cycle, on_frame)
    finally:
        if view is not None:
            _close_view(view, out)
    return _finish(args, out, res, time.perf_counter() - t0, [r["stopped"] for r in _phases(res) if r.get("stopped")])


def _run(args: argparse.Namespace, setup: SimSetup, out: Path, progress: bool,
         on_cycle: Callable[[CycleRecord], None] | None, on_frame: Callable[..., None] | None) -> dict[str, Any]:
    """Run the experiment ``args.name``, print its summary, return its result."""
    from wristmark.sim import experiments

    if args.name == "cube":
        res = experiments.run_cube(setup, out, progress=progress, duration=args.duration, on_cycle=on_cycle,
                                   on_frame=on_frame, orientation=args.orientation)
        print(experiments.cube_table(res))
    elif args.name == "point":
        res = experiments.run_point(setup, out, point=args.point, progress=progress, duration=args.duration,
                                    on_cycle=on_cycle, orientation=args.orientation)
        print(experiments.cube_table(res))
    elif args.name == "accuracy":
        res = experiments.run_accuracy(setup, out, n=args.positions, progress=progress)
        print(f"accuracy over {res['positions']} positions ({res['tracked']} tracked): "
              f"mean {res['mean_mm']:.3f} mm, max {res['max_mm']:.3f} mm "
              f"(paper: {res['paper']['mean_mm']} / {res['paper']['max_mm']} mm)")
    else:
        res = experiments.run_load(setup, out, args.forces, progress=progress, duration=args.duration,
                                   on_cycle=on_cycle, on_frame=on_frame, orientation=args.orientation)
        print((out / "results.md").read_text())
    return res


def _phases(res: dict) -> list[dict]:
    """Every phase summary in a result (cube: open/closed loop; load: those of each force)."""
    if "rows" in res:
        return [ph for row in res["rows"] for ph in (row["open_loop"], row["closed_loop"])]
    return [res[k] for k in ("open_loop", "closed_loop") if k in res]
