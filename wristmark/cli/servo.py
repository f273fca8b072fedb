"""``wristmark servo``: the closed loop driving the actuators through protocol v1 (v2 for a format-2 arm).

The hardware path, ``--serial PORT --camera SPEC``: an actuator box on a serial port (hardware,
the virtual lab's ``wristmark emulator --pty --camera-port``, any pyserial URL) and a stereo
camera named by a frame-source SPEC (docs/design.md "Stereo frame sources"), in real time on the
host's monotonic clock; the tip comes only from tracking the camera's frames, and nothing of
the simulated bench is imported.

Without ``--serial`` the command runs the simulated bench in process: the actuator-box emulator
on a new pseudo-terminal, driving the simulated true arm, talked to through
:class:`rig.link.actuator_driver.ActuatorDriver` (every command crosses the pty as bytes) while the
emulator and the loop share a simulated clock (faster than real time, deterministic);
``--realtime`` runs that emulator on the wall clock instead; ``--direct`` is the in-process
reference without serial bytes.

Safe stops (the arm held, then DISABLE; one line on stderr; exit 3): marker lost too long, the
camera stalled or its stream ended, the device silent or gone, an emergency stop, a watchdog
trip. Ctrl-C stops the same way (exit 130). Bad options fail before any motion command (exit 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cli.common_options import JSON_FILE_HELP, add_force_argument, add_host_argument, set_example
from wristmark.cli.option_types import (
    MAX_BAUD,
    MAX_DURATION_S,
    MAX_HOLD_S,
    MAX_POINT_M,
    MAX_SETTLE_S,
    MAX_TIMEOUT_S,
    MIN_BAUD,
    float_in,
    int_in,
    nonnegative_float,
    positive_float,
)
from wristmark.cli.servo_start import sigterm_as_interrupt as _sigterm_as_interrupt
from wristmark.cli.servo_start import start_configuration
from wristmark.cli.setup_args import (
    add_model_arguments,
    add_registration_argument,
    add_setup_arguments,
    setup_from_args,
)
from wristmark.cvs.tracking.warmup import warm_up
from wristmark.models.errors import InputError
from wristmark.rig.loop.servo_session import (
    HW_TIMEOUT_S,
    POINT_HOLD_S,
    SIM_TIMEOUT_S,
    LinkOptions,
    PointHold,
    ServoOutcome,
    ServoSession,
    run_servo,
)
from wristmark.rig.loop.servo_summary import percentiles_ms, summarize
from wristmark.rig.recording.output_dir import claim_outputs
from wristmark.rig.recording.run_log import write_json
from wristmark.rig.targets.live_target import (
    LIVE_DURATION_S,
    LIVE_KINDS,
    MAX_SPEED,
    TARGET_TIMEOUT_S,
    LineSource,
    LiveTargets,
    LiveTrajectory,
    Workspace,
    live_trajectory,
    open_live_targets,
    parse_target_spec,
)
from wristmark.rig.targets.orientation_path import ORIENTATION_MODES, check_orientation_mode
from wristmark.rig.targets.trajectories import Trajectory

if TYPE_CHECKING:
    from wristmark.rig.loop.loop_setup import LoopSetup

Array = NDArray[np.float64]


def add_arguments(p: argparse.ArgumentParser) -> None:
    link = p.add_mutually_exclusive_group()
    link.add_argument("--serial", metavar="PORT", action=SerialPorts,
                      help="hardware path: drive an actuator box in real time (device path or pyserial URL; "
                           "needs --camera). Default: the simulated bench, its emulator on a new pty. With --scene: "
                           "NAME=PORT, once per arm")
    link.add_argument("--direct", action="store_true",
                      help="in-process plant without serial bytes (the reference for the serial path)")
    link.add_argument("--actuator", metavar="ros2:NS", action=SerialPorts,
                      help="hardware path: an arm driven over ROS 2 (NS/servo_jp, NS/crtk_command out, "
                           "NS/measured_js, NS/operating_state in; real time; needs --camera; docs/ros2.md). With "
                           "--scene: NAME=ros2:NS, once per arm (every arm on ROS 2, or every arm on --serial)")
    p.add_argument("--no-operating-state", action="store_true",
                   help="UNSAFE, with --actuator ros2:NS: drive an arm that publishes no NS/operating_state (its "
                        "watchdog or an operator disabling it then goes unnoticed; docs/ros2.md)")
    p.set_defaults(serials=None, actuators=None)
    p.add_argument("--scene", metavar="SCENE.yaml",
                   help="hardware path, several arms in one view (a scene file): one box per arm (--serial NAME=PORT "
                        "each, or --actuator NAME=ros2:NS each), one --camera, --calib with world_T_left in the "
                        "scene's {w}; each arm walks its own cube (or --trajectory point: holds its centre); "
                        "docs/hardware.md")
    p.add_argument("--hold", action="append", metavar="NAME",
                   help="with --scene: this arm holds its workspace centre while the others walk (repeatable)")
    p.add_argument("--arm-processes", action="store_true",
                   help="with --scene: track every arm but the first in a worker process of its own (the same results; "
                        "faster only with a core to spare, e.g. on hardware, not beside a virtual lab; ~2 s to start)")
    p.add_argument("--camera", metavar="SPEC",
                   help="with --serial: the stereo camera's frame source (/dev/videoN, http://..., a video, "
                        "ros2:LEFT,RIGHT; docs/frame_sources.md); the calibration is --calib")
    p.add_argument("--camera-timeout", type=positive_float(60.0), default=2.0, metavar="S",
                   help="with --camera: no frame for S seconds ends the camera's stream (default 2)")
    p.add_argument("--record", metavar="FILE.mcap",
                   help="with --serial: record the frames, marker poses and actuators (commanded and measured) "
                        "as a ROS 2 bag; with --scene: the frames once, each arm's on /wristmark/NAME/...")
    p.add_argument("--record-jpeg", action="store_true", help="record images as JPEG (CompressedImage)")
    p.add_argument("--rt-priority", type=int_in(1, 99), metavar="N",
                   help="with --serial: run the loop (and its camera threads) under SCHED_FIFO at priority N, so a "
                        "loaded host keeps the control period (needs root or CAP_SYS_NICE)")
    p.add_argument("--realtime", action="store_true",
                   help="run the in-process emulator on the wall clock, its watchdog live, like hardware "
                        "(implied by --serial)")
    p.add_argument("--pace", action="store_true",
                   help="simulated time, but never faster than the wall clock (implied by --view)")
    p.add_argument("--baud", type=int_in(MIN_BAUD, MAX_BAUD), default=115200, help="serial baud rate (default 115200)")
    p.add_argument("--timeout", type=positive_float(MAX_TIMEOUT_S), metavar="S",
                   help=f"reply timeout per attempt [s] (default {HW_TIMEOUT_S} real time, "
                        f"{SIM_TIMEOUT_S} simulated)")
    p.add_argument("--trajectory", choices=("cube", "point"),
                   help="cube: the paper's cube walk (default); point: hold --point (same as --target)")
    p.add_argument("--target", metavar="SPEC", action=SerialPorts,
                   help="what the tip follows: cube | point (built-in, as --trajectory) | stdin | "
                        "tcp:127.0.0.1:PORT (JSON lines {\"t\": s, \"p\": [x, y, z], \"q\": [qx, qy, qz, qw]}, p in "
                        "{w} in metres, q optional; PORT 0: any free port, printed on stderr) | ros2 (NS/servo_cp, "
                        "needs --ros2); live targets: clamped to the workspace, speed bounded, held when silent. "
                        "With --scene: NAME=SPEC (stdin for one arm at most, tcp:127.0.0.1:PORT, or ros2: "
                        "NS/NAME/servo_cp, needs --ros2), repeatable; the other arms follow --trajectory or --hold")
    p.set_defaults(targets=None)
    p.add_argument("--ros2", nargs="?", const="wristmark", metavar="NS",
                   help="join the ROS 2 graph (Cyclone DDS, no ROS needed; loopback only unless CYCLONEDDS_URI "
                        "says otherwise): publish NS/measured_cp, NS/measured_js, NS/setpoint_js; with --target "
                        "ros2 follow NS/servo_cp (default NS: wristmark; docs/ros2.md). With --scene: each arm's "
                        "under NS/NAME, one participant")
    p.add_argument("--target-timeout", type=positive_float(MAX_TIMEOUT_S), default=TARGET_TIMEOUT_S, metavar="S",
                   help=f"live targets: a stream silent for S seconds holds the arm (default {TARGET_TIMEOUT_S:g})")
    p.add_argument("--max-speed", type=positive_float(0.1), default=MAX_SPEED, metavar="M/S",
                   help=f"live targets: the target's speed bound [m/s] (default {MAX_SPEED:g})")
    p.add_argument("--orientation", choices=ORIENTATION_MODES, default="none",
                   help="the tip frame's orientation: none (position only, as the paper; default), hold (the "
                        "start's, kept along the path) or follow (as the nominal model turns it); needs the qp "
                        "controller and, for the roll, the coded marker")
    p.add_argument("--point", type=float_in(-MAX_POINT_M, MAX_POINT_M), nargs=3, metavar=("X", "Y", "Z"),
                   help="point to hold in {w} [m] (default: the workspace centre)")
    p.add_argument("--duration", type=positive_float(MAX_DURATION_S), metavar="S",
                   help=f"run only the first S seconds of the trajectory (point: default {POINT_HOLD_S:g}; "
                        f"live targets: default {LIVE_DURATION_S:g})")
    p.add_argument("--settle", type=nonnegative_float(MAX_SETTLE_S), metavar="S",
                   help="closed-loop approach to the start [s] (rig file)")
    p.add_argument("--json", metavar="FILE.json", help=JSON_FILE_HELP.format(what="the result"))
    p.add_argument("--out", metavar="DIR",
                   help="output folder: config.json, log.csv, result.json (empty unless --force)")
    add_force_argument(p)
    add_registration_argument(p)
    add_setup_arguments(p)
    add_model_arguments(p, per_arm=True)
    p.add_argument("--view", action="store_true",
                   help="show the run live in the Meshcat view (paced); with --scene every arm")
    add_host_argument(p)
    p.add_argument("--view-hold", type=nonnegative_float(MAX_HOLD_S), default=0.0, metavar="S",
                   help="with --view: keep serving the view S seconds after the run (Ctrl-C ends it)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    set_example(p, "wristmark servo --trajectory cube --duration 10 --out runs/servo",
                "wristmark servo --serial /dev/pts/3 --camera http://127.0.0.1:41234/stream.mjpg --image-scale 0.35 "
                "--duration 20 --out runs/lab",
                "wristmark servo --scene configs/scenes/two_arms.yaml --serial a=/dev/pts/3 --serial b=/dev/pts/4 "
                "--camera http://127.0.0.1:41234/stream.mjpg --calib lab_calib.yaml --image-scale 0.35 --out runs/two")


class SerialPorts(argparse.Action):
    """``--serial PORT`` (``--target SPEC``, ``--actuator ros2:NS``), repeatable for ``--scene``
    (``NAME=PORT``, ``NAME=SPEC``, ``NAME=ros2:NS``): every value in ``serials`` (``targets``,
    ``actuators``), the first in ``serial`` (``target``, ``actuator``)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        setattr(namespace, f"{self.dest}s", [*(getattr(namespace, f"{self.dest}s", None) or []), values])
        if getattr(namespace, self.dest, None) is None:
            setattr(namespace, self.dest, values)


# -- command line ------------------------------------------------------------------------------
def build_setup(args: argparse.Namespace) -> LoopSetup:
    """The setup with the command-line overrides, validated: the simulated bench's SimSetup, or
    for the hardware path (``--serial``) a LoopSetup without the simulated bench."""
    return setup_from_args(args, simulated=not hardware(args), settle_time=args.settle)  # type: ignore[no-any-return]


def target_kind(args: argparse.Namespace) -> tuple[str, int | None]:
    """What the tip follows (cube | point | stdin | tcp | ros2) and the TCP port, from
    ``--target`` or ``--trajectory`` (not both)."""
    if args.target is not None and args.trajectory is not None:
        raise InputError("give --target SPEC or --trajectory, not both")
    kind, _, port = parse_target_spec(args.target or args.trajectory or "cube")
    return kind, port


def build_trajectory(setup: LoopSetup, kind: str, point: list[float] | None, duration: float | None) -> Trajectory:
    """The cube walk around the workspace centre, or a held point; cut to ``duration`` [s]; a
    live kind (stdin | tcp | ros2): waiting at the workspace centre for ``duration`` (default
    LIVE_DURATION_S), its targets attached later (LiveTrajectory.with_follower)."""
    from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, cube_trajectory, workspace_centre

    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise InputError(f"--duration must be > 0 s, got {duration}")
    if point is not None and kind != "point":
        raise InputError("--point needs --trajectory point")
    centre = workspace_centre(setup.params)
    if kind in LIVE_KINDS:
        return live_trajectory(centre, duration if duration is not None else LIVE_DURATION_S, kind)
    if kind == "point":
        p = np.asarray(point if point is not None else centre, float)
        if not np.all(np.isfinite(p)):
            raise InputError(f"--point must be 3 finite numbers [m], got {p.tolist()}")
        return PointHold(np.array([p]), 1.0, hold=duration if duration is not None else POINT_HOLD_S)
    traj = cube_trajectory(centre, CUBE_SIZE, CUBE_SPEED)
    return traj.truncated(duration) if duration is not None else traj


def live_view(setup: LoopSetup, host: str | None = None) -> Any:
    """The Meshcat live view (viz.live.start_live_view), or a one-line error when it is missing."""
    try:
        from wristmark.viz.live import start_live_view  # type: ignore[import-not-found, unused-ignore]
    except ImportError as e:
        raise InputError(f"--view needs the Meshcat live view (viz/live.py), which is not available: {e}") from None
    return start_live_view(setup, host=host)


def hardware(args: argparse.Namespace) -> bool:
    """The hardware path: ``--serial PORT`` or ``--actuator ros2:NS`` (a real-time link and a camera)."""
    return args.serial is not None or getattr(args, "actuator", None) is not None


def actuator_namespace(spec: str) -> str:
    """``--actuator ros2:NS`` -> NS (InputError, one line, for anything else)."""
    from wristmark.rig.ros2.bridge import clean_namespace

    if not spec.startswith("ros2:"):
        raise InputError(f"--actuator must be ros2:NS (an arm on a ROS 2 graph), got {spec!r}")
    try:
        return clean_namespace(spec[len("ros2:"):] or "-")
    except ValueError as e:
        raise InputError(f"--actuator: {e}") from None


def _same_namespace(a: str, b: str) -> bool:
    from wristmark.rig.ros2.bridge import clean_namespace

    try:
        return clean_namespace(a) == clean_namespace(b)
    except ValueError:
        return False


def check_link_options(args: argparse.Namespace) -> None:
    """The link and camera options fit together (InputError before anything is opened)."""
    if args.actuator is not None:
        actuator_namespace(args.actuator)
        if not args.camera:
            raise InputError("--actuator ros2:NS needs --camera SPEC: the frames of the stereo camera")
        check_ros2(args.actuator[len("ros2:"):], "--actuator")
        if args.ros2 is not None and _same_namespace(args.ros2, args.actuator[len("ros2:"):]):
            raise InputError("--ros2 NS must differ from --actuator ros2:NS: the loop would read its own "
                             "measured_js back as the arm's")
    if args.no_operating_state and args.actuator is None:
        raise InputError("--no-operating-state is for --actuator ros2:NS")
    if args.serial is not None and not args.camera:
        raise InputError("--serial needs --camera SPEC: the frames of the stereo camera (e.g. the virtual lab's "
                         "stream URL); the simulated cameras exist only in the in-process bench (no --serial)")
    if args.camera and not hardware(args):
        raise InputError("--camera SPEC needs --serial PORT or --actuator ros2:NS (the hardware path); without "
                         "them the simulated bench renders its own frames")
    if args.rt_priority is not None and not hardware(args):
        raise InputError("--rt-priority is for the hardware path (--serial); the simulated bench runs in "
                         "simulated time")
    if args.record and not hardware(args):
        raise InputError("--record is for the hardware path (--serial --camera): the simulated bench writes "
                         "log.csv with --out")
    if args.record_jpeg and not args.record:
        raise InputError("--record-jpeg needs --record FILE.mcap")
    if hardware(args) and args.realtime:
        raise InputError("--realtime is for the in-process emulator; --serial is always real time")
    if args.timeout is not None and not args.timeout > 0:
        raise InputError(f"--timeout must be > 0 s, got {args.timeout}")
    if args.baud <= 0:
        raise InputError(f"--baud must be > 0, got {args.baud}")
    if not (np.isfinite(args.view_hold) and args.view_hold >= 0):
        raise InputError(f"--view-hold must be >= 0 s, got {args.view_hold}")


def open_session(setup: LoopSetup, psi0: Array, options: LinkOptions, args: argparse.Namespace) -> ServoSession:
    """The hardware session (serial port + camera), or the simulated bench's in process."""
    if options.kind in ("serial", "ros2"):
        from wristmark.rig.loop.hardware_session import open_hardware_session

        if args.rt_priority is not None:  # before any thread starts: the camera's threads inherit it
            from wristmark.rig.loop.realtime_priority import request_realtime_priority

            request_realtime_priority(args.rt_priority)
        from wristmark.rig.loop.heap_freeze import freeze_heap

        session = open_hardware_session(setup, options, args.camera, camera_timeout=args.camera_timeout)
        freeze_heap()  # no full garbage collection of the start-up heap mid-run (rig.loop.heap_freeze)
        return session
    from wristmark.sim.servo_bench import open_sim_session

    return open_sim_session(setup, psi0, options, seed=setup.rig.seed)  # type: ignore[arg-type]


def open_recorder(args: argparse.Namespace, setup: LoopSetup, session: ServoSession) -> Any:
    """The --record bag (after the session opened, before any motion); closes the session when
    the bag cannot be written."""
    if not args.record:
        return None
    from wristmark.rig.recording.servo_recorder import ServoRecorder

    try:
        return ServoRecorder(args.record, setup.params, jpeg=args.record_jpeg,
                             world_T_left=setup.host_camera.T_world_left)
    except BaseException:
        session.close()
        raise


def write_outputs(args: argparse.Namespace, setup: LoopSetup, out: ServoOutcome, res: dict[str, Any]) -> None:
    """DIR/config.json, DIR/log.csv, DIR/result.json (--out) and the result JSON (--json)."""
    if args.out:
        out_dir = Path(args.out)
        out_dir.mkdir(parents=True, exist_ok=True)
        write_json(out_dir / "config.json", {"command": "servo", "link": res["link"], "camera": args.camera,
                                             **setup.describe()})
        out.log.write_csv(out_dir / "log.csv")
        write_json(out_dir / "result.json", {**res, "run_dir": str(out_dir)})
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, res)


def open_targets(args: argparse.Namespace, setup: LoopSetup, traj: Trajectory, port: int | None
                 ) -> tuple[Trajectory, LiveTargets | None, LineSource | None]:
    """A live trajectory's target store and its source (stdin, TCP; ros2: the bridge feeds it),
    attached to the trajectory; built-in trajectories are returned as they are."""
    if not isinstance(traj, LiveTrajectory):
        return traj, None, None
    return open_live_targets(traj, Workspace.around(traj.waypoints[0]), port, args.target_timeout,
                             args.max_speed, f"--target {args.target}")


def check_ros2(namespace: str, what: str = "--ros2") -> None:
    """``--ros2 NS``: a valid namespace and cyclonedds installed (InputError, one line)."""
    from wristmark.rig.ros2.bridge import check_namespace_option

    check_namespace_option(namespace, what)


def cycle_hook(view: Any, bridge: Any, session: ServoSession) -> Any:
    """The loop's per-cycle hook: the live view's and the ROS 2 bridge's (None: neither)."""
    if bridge is None:
        return None if view is None else view.on_cycle

    def hook(rec: Any) -> None:
        bridge.on_cycle(rec, session.link)
        if view is not None:
            view.on_cycle(rec)

    return hook


def run(args: argparse.Namespace) -> int:
    if args.scene is not None:
        from wristmark.cli.servo_scene import run_scene

        return run_scene(args)
    if args.hold:
        raise InputError("--hold needs --scene (several arms in one view)")
    if args.arm_processes:
        raise InputError("--arm-processes needs --scene (several arms in one view)")
    if args.serials and len(args.serials) > 1:
        raise InputError(f"--serial given {len(args.serials)} times: several actuator boxes need --scene SCENE "
                         "(--serial NAME=PORT per arm)")
    if args.actuators and len(args.actuators) > 1:
        raise InputError(f"--actuator given {len(args.actuators)} times: several arms need --scene SCENE "
                         "(--actuator NAME=ros2:NS per arm)")
    if args.targets and len(args.targets) > 1:
        raise InputError(f"--target given {len(args.targets)} times: several arms' targets need --scene SCENE "
                         "(--target NAME=SPEC per arm)")
    check_link_options(args)
    setup = build_setup(args)
    target, port = target_kind(args)
    traj = build_trajectory(setup, target, args.point, args.duration)
    if target == "ros2" and args.ros2 is None:
        raise InputError("--target ros2 needs --ros2 [NS]: the targets come from NS/servo_cp")
    if args.ros2 is not None:
        check_ros2(args.ros2)
    if check_orientation_mode(args.orientation, setup.controller.kind) != "none":
        if isinstance(traj, LiveTrajectory) and args.orientation != "hold":
            raise InputError("live targets take --orientation none or hold (q of each target turns the tip)")
        traj = traj.with_orientation(args.orientation, setup.params)
    psi0 = start_configuration(setup, traj)
    claim_outputs(dirs=[args.out], files=[args.json], force=args.force)  # after every option was validated
    warm_up()  # OpenCV's threads and the tracker's kernels, before the link opens (cvs.tracking.warmup)
    kind = "serial" if args.serial else "ros2" if args.actuator else "direct" if args.direct else "emulator"
    live = isinstance(traj, LiveTrajectory)  # a device steers in real time: the simulated bench is paced
    options = LinkOptions(kind=kind, port=actuator_namespace(args.actuator) if args.actuator else args.serial,
                          baudrate=args.baud, timeout=args.timeout,
                          realtime=bool(args.realtime), pace=bool(args.pace or args.view or live),
                          operating_state=not args.no_operating_state)
    traj, targets, source = open_targets(args, setup, traj, port)
    bridge = None
    with _sigterm_as_interrupt():
        view = live_view(setup, args.host) if args.view else None
        try:
            if args.ros2 is not None:
                from wristmark.rig.ros2.bridge import Ros2Bridge

                bridge = Ros2Bridge(args.ros2, setup.params, targets if target == "ros2" else None,
                                    wall_clock=options.kind in ("serial", "ros2"))
            session = open_session(setup, psi0, options, args)
            recorder = open_recorder(args, setup, session)
            out = run_servo(setup, traj, session, psi0, settle=setup.rig.settle_time,
                            progress=not args.no_progress, on_cycle=cycle_hook(view, bridge, session),
                            recorder=recorder, on_frame=None if view is None else view.on_frame)
            if view is not None and args.view_hold > 0:
                view.hold(args.view_hold)
        finally:
            if view is not None:
                view.close()
            if source is not None:
                source.close()
            if bridge is not None:
                bridge.close()
    res = summarize(setup, traj, session, out)
    if options.kind == "ros2":  # targets sent, malformed measured_js (rig/ros2/actuator_link.py)
        res["link"].update(session.link.stats())  # type: ignore[attr-defined]
    if bridge is not None:
        res["ros2"] = bridge.report()
    if targets is not None:
        res["trajectory"]["kind"] = target
        res["targets"] = {"source": source.describe if source is not None else target,
                          "max_speed_mps": args.max_speed, **targets.report()}
    if session.wall_clock:  # the host's own work after a frame's arrival, before the command instant
        res["latency"]["arrival_to_ready"] = percentiles_ms(np.asarray(out.ready_after_arrival_ms, float))
        res["latency"]["command_phase_ms"] = 1000.0 * setup.rig.command_phase
        res["closed_loop"]["reused"] = out.reused  # cycles without a frame (or marker) driven by the last measurement
        if setup.rig.frame_phase_lock != "none":  # the cycle locked to the frames (second half: locked)
            late = np.asarray(out.frame_lock_offsets_ms[len(out.frame_lock_offsets_ms) // 2:], float)
            res["timing"]["phase_lock"] = {
                "on": setup.rig.frame_phase_lock, "target_ms": 1000.0 * setup.rig.frame_lock_phase,
                "shift_ms": out.phase_shift_ms, "after_start": percentiles_ms(late),
                "after_start_p5_ms": float(np.percentile(late, 5)) if late.size else None}
    if recorder is not None:
        res["recording"] = {"path": args.record, "cycles": recorder.cycles, "dropped_cycles": recorder.dropped,
                            "messages": recorder.bag.messages, "problem": recorder.error}
    write_outputs(args, setup, out, res)
    c = res["closed_loop"]
    errors = (f"closed-loop tip error mean {c['mean_mm']:.3f} mm, max {c['max_mm']:.3f} mm over {c['cycles']} "
              f"cycles ({c['errors_from']} vs desired)" if c["cycles"] else "no trajectory cycle ran")
    if c["cycles"] and "orientation_mean_deg" in c:
        errors += f"; orientation mean {c['orientation_mean_deg']:.2f} deg, max {c['orientation_max_deg']:.2f} deg"
    lat = res["latency"]["capture_to_command"]
    hw_link = options.kind in ("serial", "ros2")
    latency = f"; capture -> command median {lat['median_ms']:.1f} ms" if hw_link and lat["n"] else ""
    print(f"servo ({res['trajectory']['kind']}, {traj.duration:.1f} s, controller {res['controller']}, "
          f"sensor {res['sensor']}, link {kind} {session.port}): {errors}{latency}")
    if not out.stopped:
        return 0
    safe = ("arm held and disabled" if not out.close_error
            else f"could not confirm hold/disable ({out.close_error})")
    when = f"at t = {out.t_stop:.2f} s" if np.isfinite(out.t_stop) else "before the first target"
    print(f"wristmark servo: error: stopped safely {when}: {out.stopped}; {safe}", file=sys.stderr)
    return 130 if out.cause == "interrupted" else 3
