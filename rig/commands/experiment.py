"""``wristmark experiment {cube,accuracy,load}``: the paper's experiments on the simulated bench."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from models.errors import ConfigError
from rig.commands.setup_args import add_setup_arguments, setup_from_args
from rig.run_log import write_json

if TYPE_CHECKING:
    from rig.run_log import CycleRecord
    from sim.setup import SimSetup


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", choices=("cube", "accuracy", "load"), help="which experiment")
    p.add_argument("--json", metavar="OUT", help="write the result JSON to OUT")
    p.add_argument("--out", metavar="DIR", help="run folder (default: runs/<name>-<time>)")
    add_setup_arguments(p)
    p.add_argument("--duration", type=float, metavar="S",
                   help="cube/load: run only the first S seconds of the cube walk (quick checks)")
    p.add_argument("--positions", type=int, default=40, help="accuracy: number of positions")
    p.add_argument("--forces", type=float, nargs="+", default=[0.0, 0.1, 0.2, 0.3],
                   help="load: tip forces [N] to sweep")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--view", action="store_true",
                   help="live 3D view in the browser (Meshcat; prints the URL to open)")


def run(args: argparse.Namespace) -> int:
    if args.duration is not None and not args.duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {args.duration}")
    setup = setup_from_args(args)
    out = Path(args.out) if args.out else Path("runs") / f"{args.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    progress = not args.no_progress
    t0 = time.perf_counter()
    view = None
    if args.view:
        from viz.live import start_live_view

        view = start_live_view(setup)
    on_cycle = view.on_cycle if view is not None else None
    on_frame = view.on_frame if view is not None else None
    try:
        res = _run(args, setup, out, progress, on_cycle, on_frame)
    finally:
        if view is not None:
            view.close()
            print(f"replay in the browser: wristmark view {out}", file=sys.stderr)
    res["wall_time_s"] = time.perf_counter() - t0
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, res)
    print(f"run folder: {out}")
    stopped = [r for r in _phases(res) if r.get("stopped")]
    if stopped:
        print(f"wristmark experiment: error: closed loop stopped safely: {stopped[0]['stopped']}", file=sys.stderr)
        return 3
    return 0


def _run(args: argparse.Namespace, setup: SimSetup, out: Path, progress: bool,
         on_cycle: Callable[[CycleRecord], None] | None, on_frame: Callable[..., None] | None) -> dict[str, Any]:
    """Run the experiment ``args.name``, print its summary, return its result."""
    from sim import experiments

    if args.name == "cube":
        res = experiments.run_cube(setup, out, progress=progress, duration=args.duration, on_cycle=on_cycle,
                                   on_frame=on_frame)
        print(experiments.cube_table(res))
    elif args.name == "accuracy":
        res = experiments.run_accuracy(setup, out, n=args.positions, progress=progress)
        print(f"accuracy over {res['positions']} positions ({res['tracked']} tracked): "
              f"mean {res['mean_mm']:.3f} mm, max {res['max_mm']:.3f} mm "
              f"(paper: {res['paper']['mean_mm']} / {res['paper']['max_mm']} mm)")
    else:
        res = experiments.run_load(setup, out, args.forces, progress=progress, duration=args.duration,
                                   on_cycle=on_cycle, on_frame=on_frame)
        print((out / "results.md").read_text())
    return res


def _phases(res: dict) -> list[dict]:
    """Every phase summary in a result (cube: open/closed loop; load: those of each force)."""
    if "rows" in res:
        return [ph for row in res["rows"] for ph in (row["open_loop"], row["closed_loop"])]
    return [res[k] for k in ("open_loop", "closed_loop") if k in res]
