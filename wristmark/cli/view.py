"""``wristmark view [RUN_DIR]``: the Meshcat 3D view of a run (replay) or of the arm at home.

Without ``--snapshot`` it serves the scene: the first stdout line is ``open URL`` (with
``--json``: ``{"url": URL}``), then it serves until Ctrl-C, SIGTERM or ``--serve-seconds``.
A RUN_DIR is replayed as an animation with a time slider (the control panel opens on it); a
run folder of several arms (``experiment cube --scene``: log_<arm>.csv per arm) shows every arm.
``--snapshot OUT.html`` writes a self-contained page that opens from a file instead.
Errors (missing run folder, corrupt log.csv, unwritable OUT) are one line on stderr, exit 2.
The live view of a running loop is ``--view`` on ``wristmark experiment``/``servo``.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time
from types import FrameType
from typing import Any

from wristmark.cli.common_options import (
    add_config_option,
    add_force_argument,
    add_host_argument,
    add_json_flag,
    set_example,
)
from wristmark.cli.option_types import MAX_FRAMES, MAX_HOLD_S, int_in, nonnegative_float
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run_dir", nargs="?", metavar="RUN_DIR",
                   help="experiment run folder to replay (log.csv + config.json, or log_<arm>.csv per arm of a "
                        "--scene run); none: the arm at home")
    p.add_argument("--snapshot", metavar="OUT.html", help="write a self-contained static HTML page and exit")
    p.add_argument("--serve-seconds", type=nonnegative_float(MAX_HOLD_S), metavar="S",
                   help="serve for S seconds, then exit (default: until Ctrl-C / SIGTERM)")
    p.add_argument("--max-frames", type=int_in(2, MAX_FRAMES), default=None, metavar="N",
                   help="key frames of a replay at most (longer runs are decimated; default 1000)")
    p.add_argument("--no-play", action="store_true", help="served replay: do not start playing")
    add_config_option(p, "--robot", note="home view only")
    add_config_option(p, "--marker", note="home view only")
    add_config_option(p, "--calib", note="home view only")
    add_json_flag(p, "the URL or the written file")
    add_force_argument(p)
    add_host_argument(p)
    set_example(p, "wristmark view runs/latest", "wristmark view --snapshot runs/tour/view.html")


def _stop_on_sigterm(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    from wristmark.viz.replay import DEFAULT_MAX_FRAMES, RunReplay, build_replay, home_scene, load_run
    from wristmark.viz.scene import SceneConfig
    from wristmark.viz.scene_replay import SceneRunReplay, build_scene_replay, is_scene_run, load_scene_run

    if args.serve_seconds is not None and not args.serve_seconds >= 0:
        raise InputError(f"--serve-seconds must be >= 0, got {args.serve_seconds}")
    max_frames = DEFAULT_MAX_FRAMES if args.max_frames is None else args.max_frames
    if max_frames < 2:
        raise InputError(f"--max-frames must be >= 2, got {max_frames}")
    if args.run_dir and (args.robot or args.marker or args.calib):
        raise InputError("--robot/--marker/--calib set the home view; a replay uses the run's config.json")
    replay: RunReplay | SceneRunReplay | None = None
    if args.run_dir:
        replay = load_scene_run(args.run_dir) if is_scene_run(args.run_dir) else load_run(args.run_dir)
    config: SceneConfig | None = None
    if replay is None:
        from wristmark.sim.setup import load_setup

        config = SceneConfig.from_setup(load_setup(robot=args.robot, marker=args.marker, camera=args.calib))
    title = f"wristmark replay: {replay.run_dir.name}" if replay else "wristmark: arm at home"
    status = replay.summary if replay else {"configuration": f"home ({_arm_label(config)})"}
    legend = replay.legend if isinstance(replay, SceneRunReplay) else None

    def draw(vis: Any, play: bool) -> None:
        if isinstance(replay, SceneRunReplay):
            build_scene_replay(vis, replay, max_frames, play=play)
        elif replay is not None:
            build_replay(vis, replay, max_frames, play=play)
        else:
            home_scene(vis, config)

    if args.snapshot:
        from wristmark.viz.snapshot import recording_visualizer, write_html

        claim_outputs(files=[args.snapshot], force=args.force)
        vis, window = recording_visualizer()
        draw(vis, False)
        out = write_html(args.snapshot, window.html(title, status, open_controls=replay is not None, legend=legend))
        size = out.stat().st_size
        if args.json:
            print(json.dumps({"snapshot": str(out), "bytes": size}))
        else:
            print(f"wrote {out} ({size / 1e6:.1f} MB): open it in a browser")
        return 0

    from wristmark.viz.viewer_client import MeshcatServer

    server = MeshcatServer.start(title=title, controls=replay is not None, host=args.host, legend=legend)
    previous = signal.signal(signal.SIGTERM, _stop_on_sigterm)
    try:
        vis = server.visualizer()
        with vis.window.batch():
            draw(vis, not args.no_play)
        vis.window.send_status(status)
        print(json.dumps({"url": server.url}) if args.json else f"open {server.url}", flush=True)
        if not args.json:
            print("serving; Ctrl-C to stop", file=sys.stderr, flush=True)
        deadline = None if args.serve_seconds is None else time.monotonic() + args.serve_seconds
        while deadline is None or time.monotonic() < deadline:
            time.sleep(0.2 if deadline is None else max(0.0, min(0.2, deadline - time.monotonic())))
            if server.proc.poll() is not None:
                raise InputError("the Meshcat server exited unexpectedly")
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        server.close()
    return 0



def _arm_label(config: object) -> str:
    """The home view's arm: the format-2 robot file's name, or HOME_PSI for the reference arm."""
    from wristmark.models.arm_spec import ArmSpec

    params = getattr(config, "params", None)
    return f"arm {params.name}" if isinstance(params, ArmSpec) else "HOME_PSI"
