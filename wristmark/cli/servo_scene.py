"""``wristmark servo --scene SCENE --serial NAME=PORT ... --camera SPEC --calib C``: several arms
on the hardware path, one process, one camera, one actuator box per arm (rig.loop.arm_set_session;
docs/hardware.md "Several arms"). Imports nothing of the simulated bench.

``--actuator NAME=ros2:NS`` per arm instead of ``--serial``: each arm's driver on a ROS 2 graph
(rig.ros2.actuator_link; every arm, never mixed with serial boxes), one DDS participant for the
process shared by the links, a ``ros2:`` camera and the ``--ros2`` bridges; an arm disabled or
silent is a safe stop of every arm, as a box's emergency stop (docs/ros2.md "Several arms").

Bad input is refused in one line (exit 2) before any motion command: an option that has no
meaning with a scene, a missing, unknown or repeated arm, a port or namespace given twice, a
``--ros2 NS`` that would publish on an arm driver's namespace, a box that does not answer or does
not fit its arm, a start out of reach or arms too close at their starts. The
output folder (``--out``) has config.json, log_<arm>.csv per arm and result.json (per arm the
one-arm servo's fields, and the clearance); exit 3 when an arm stopped safely.

``--record FILE.mcap`` (``--record-jpeg``): one ROS 2 bag of the run, the camera's frames once and
each arm's marker pose, tip and actuators on its own topics (``/wristmark/NAME/...``;
rig.recording.bag_recorder). The run folder ``--out DIR`` is what ``wristmark view DIR`` replays.
``--view``: the live Meshcat view of every arm while the loops run (viz.live, as ``experiment cube
--scene --view``; served on 127.0.0.1 unless ``--host``), its counts in result.json ``view``.
``--model NAME=MODEL.yaml`` (repeatable): that arm's loop commands its identified arm, as the
one-arm ``--model`` (rig.loop.model_loop); the file named in that arm's ``model`` of result.json.

``--target NAME=SPEC`` (stdin for one arm at most, or ``tcp:127.0.0.1:PORT``): that arm follows
live targets in its own {w} as the one-arm servo does (rig.targets.live_target: speed bound,
workspace clamp, hold when silent, malformed lines dropped and counted; its counts in its
``targets`` of result.json); the others walk ``--trajectory`` or ``--hold``.

``--ros2 [NS]``: every arm on one ROS 2 graph (rig.ros2.scene_bridge: one participant, each arm's
``NS/NAME/measured_cp``, ``marker/measured_cp``, ``measured_js``, ``setpoint_js`` in the scene's
{w}); ``--target NAME=ros2`` follows ``NS/NAME/servo_cp``. Its topics and counts in the arm's
``ros2`` of result.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import sys
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.models.errors import InputError, WristmarkError

SCENE_REFUSED = ("robot", "marker", "plant", "registration", "open_loop_on_lost", "point",
                 "direct", "realtime", "pace", "latency", "sensor")


def check_scene_options(args: argparse.Namespace) -> None:
    """The options ``--scene`` takes on the hardware path (InputError naming the others)."""
    if args.orientation == "follow" and args.targets:
        raise InputError("live targets take --orientation none or hold (q of each target turns the tip)")
    if getattr(args, "no_operating_state", False):
        raise InputError("--no-operating-state: not with --scene (every arm's driver must publish its "
                         "NS/operating_state: a disabled arm stops every arm)")
    given = [f"--{k.replace('_', '-')}" for k in SCENE_REFUSED if getattr(args, k, None) not in (None, False)]
    if args.view_hold:
        given.append("--view-hold")
    if given:
        raise InputError(f"{', '.join(given)}: not with --scene (each arm's files are named in the scene file; "
                         "each arm walks its own cube, holds its centre or follows --target NAME=SPEC; position only)")
    if not (args.serials or getattr(args, "actuators", None)) or not args.camera or not args.calib:
        raise InputError("--scene on the hardware path needs --serial NAME=PORT (or --actuator NAME=ros2:NS) for "
                         "every arm, --camera SPEC and --calib C (world_T_left in the scene's {w}: the virtual lab's "
                         "--calib-out)")
    if args.host and not args.view:
        raise InputError("--host serves the live view on another address too: it needs --view")
    if args.record_jpeg and not args.record:
        raise InputError("--record-jpeg needs --record FILE.mcap")
    if args.record is not None:
        check_record_path(args.record, args.force)
    if args.ros2 is not None:
        from wristmark.rig.ros2.bridge import check_namespace_option

        check_namespace_option(args.ros2)


def check_record_path(path: str, force: bool = False) -> None:
    """``--record FILE.mcap``: an .mcap file in an existing folder, not there yet (InputError)."""
    rec = Path(path)
    if rec.suffix.lower() != ".mcap":
        raise InputError(f"--record {path}: a recording must be an .mcap file (a ROS 2 bag); the run folder "
                         "(log_<arm>.csv, result.json: `wristmark view DIR`) is --out DIR")
    if rec.exists():
        raise InputError(f"--record {path}: exists already; not overwriting a recording (remove it or pick another)")
    if not rec.parent.is_dir():
        raise InputError(f"--record {path}: folder {rec.parent} does not exist")


def run_scene(args: argparse.Namespace) -> int:
    """``servo --scene``: every arm's loop on one camera (see the module docstring)."""
    from wristmark.cli.servo_start import sigterm_as_interrupt, start_configuration
    from wristmark.cli.setup_args import apply_overrides
    from wristmark.cvs.tracking.warmup import warm_up
    from wristmark.models.errors import ConfigError
    from wristmark.rig.loop.arm_set_session import (
        arm_trajectories,
        check_arm_orientation,
        load_scene_setups,
        open_arm_set_session,
        parse_actuator_specs,
        parse_serial_specs,
        parse_target_specs,
        run_arm_set,
        start_gap,
    )
    from wristmark.rig.loop.scene_file import Scene
    from wristmark.rig.loop.servo_session import LinkOptions
    from wristmark.rig.recording.output_dir import claim_outputs
    from wristmark.rig.targets.live_target import (
        LIVE_DURATION_S,
        Workspace,
        live_trajectory,
        open_live_targets,
    )
    from wristmark.rig.targets.trajectories import workspace_centre

    check_scene_options(args)
    scene = Scene.load(args.scene)
    kind = "ros2" if getattr(args, "actuators", None) else "serial"  # argparse refuses --serial with --actuator
    ports = (parse_actuator_specs(args.actuators, scene.names) if kind == "ros2"
             else parse_serial_specs(args.serials, scene.names))  # {arm: port or ROS 2 namespace}
    hold = tuple(args.hold or ())
    live = parse_target_specs(args.targets or (), scene.names, hold, ros2=args.ros2 is not None)
    if args.ros2 is not None:  # every arm's namespace a valid ROS 2 name, none an arm driver's
        published = scene_namespaces(args.ros2, scene.names)
        if kind == "ros2":
            check_own_topics(published, ports)
    setups, scene_camera = load_scene_setups(scene, args.calib, rig=args.rig, controller=args.controller_config)
    models = load_scene_models(args.model or (), scene.names, setups)  # {arm: MODEL.yaml} of --model NAME=FILE
    for n, s in setups.items():  # the command line's overrides; one grid for every arm (rig.loop.arm_set_session)
        s = apply_overrides(s, args, settle_time=args.settle)
        setups[n] = s.with_changes(rig=dataclasses.replace(s.rig, frame_phase_lock="none"))
    check_arm_orientation(args.orientation, {n: s.controller.kind for n, s in setups.items()})
    trajs = arm_trajectories({n: s.params for n, s in setups.items()}, scene.cube_size,
                             args.trajectory or "cube", args.duration, hold, args.orientation)
    centres = {n: workspace_centre(setups[n].params, scene.cube_size) for n in live}
    length = args.duration if args.duration is not None else LIVE_DURATION_S
    lives = {n: live_trajectory(centres[n], length, kind) for n, (kind, _) in live.items()}  # in its own {w}
    if args.orientation != "none":  # hold: the tip frame's orientation at the centre (q of a target turns it)
        lives = {n: t.with_orientation(args.orientation, setups[n].params) for n, t in lives.items()}
    trajs.update(lives)  # waiting at its centre for its targets
    psi0 = {}
    for n, s in setups.items():
        try:
            psi0[n] = start_configuration(s, trajs[n])
        except InputError as e:
            raise InputError(f"arm '{n}': {e}") from None
    bases = {a.name: a.base for a in scene.arms}
    gap = start_gap(setups, psi0, bases)
    if gap < scene.clearance:
        raise ConfigError(f"{scene.source}: the arms' bodies come {1000 * gap:.1f} mm close at the start of their "
                          f"paths, under the clearance {1000 * scene.clearance:.1f} mm")
    claim_outputs(dirs=[args.out], files=[args.json], force=args.force)  # after every option was validated
    warm_up()
    options = LinkOptions(kind=kind, port=None, baudrate=args.baud, timeout=args.timeout)
    # the live view's server and drawing process first: they do not inherit the loop's priority
    view, view_lines = start_scene_view(setups, scene_camera, bases, args.host) if args.view else (None, "")
    if args.rt_priority is not None:  # before any thread starts: the camera's threads inherit it
        from wristmark.rig.loop.realtime_priority import request_realtime_priority

        try:
            request_realtime_priority(args.rt_priority)
        except BaseException:
            if view is not None:
                view.close()
            raise
    stores, sources = {}, {}
    bridges = None
    participant = None  # one DDS participant for the process: the arms' links, a ros2: camera, the bridges
    try:
        if kind == "ros2" or args.ros2 is not None:
            from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds

            require_cyclonedds("--actuator NAME=ros2:NS" if kind == "ros2" else "--ros2")
            participant = open_participant()
        for n, (_, port) in live.items():  # each arm's own server (before any box opens: a port taken is exit 2)
            trajs[n], stores[n], sources[n] = open_live_targets(
                lives[n], Workspace.around(centres[n], scene.cube_size), port, args.target_timeout, args.max_speed,
                f"arm {n}'s targets", who=f"arm {n} ")
        print(view_lines, end="", file=sys.stderr, flush=True)  # the view's URL after the targets' ports
        if args.ros2 is not None:  # before any box opens: servo_cp heard from the start
            from wristmark.rig.ros2.scene_bridge import SceneBridges

            bridges = SceneBridges(args.ros2, {n: s.params for n, s in setups.items()}, bases,
                                   {n: stores[n] for n, (how, _) in live.items() if how == "ros2"},
                                   participant=participant)
        session = open_arm_set_session(setups, ports, args.camera, scene_camera, options,
                                       camera_timeout=args.camera_timeout, participant=participant,
                                       processes=args.arm_processes)
        if bridges is not None:
            bridges.links = dict(session.links)
        recorder = open_scene_recorder(args, setups, scene_camera, session)
        from wristmark.rig.loop.heap_freeze import freeze_heap

        freeze_heap()  # no full garbage collection of the start-up heap mid-run (rig.loop.heap_freeze)
        clearance = scene.clearance + scene.clearance_margin if scene.clearance > 0 else 0.0
        settle = next(iter(setups.values())).rig.settle_time
        with sigterm_as_interrupt():
            run = run_arm_set(setups, trajs, session, psi0, bases, clearance, settle, recorder=recorder,
                              on_cycle=arm_cycle_hook(view, bridges))
    finally:
        for src in sources.values():
            if src is not None:
                src.close()
        if view is not None:
            view.close()
        if bridges is not None:
            bridges.close()
    res = scene_result(args, scene, setups, trajs, session, run, hold)
    for n, path in models.items():  # the identified arm each such arm's loop commanded through
        res["arms"][n]["model"] = path
    for n, store in stores.items():
        src = sources[n]
        res["arms"][n]["targets"] = {"source": src.describe if src is not None else live[n][0],
                                     "max_speed_mps": args.max_speed, **store.report()}
    if kind == "ros2":  # each arm's targets sent, malformed measured_js (rig/ros2/actuator_link.py)
        for n, link in session.links.items():
            res["arms"][n]["link"].update(link.stats())
    if bridges is not None:
        for n, r in bridges.report().items():
            res["arms"][n]["ros2"] = r
    if view is not None:
        st = view.stats
        res["view"] = {"url": view.url, "sent": st.sent, "dropped": st.dropped, "received": st.received,
                       "frames": st.frames, "problem": st.error}
    if recorder is not None:
        res["recording"] = {"path": args.record, "cycles": recorder.cycles, "dropped_cycles": recorder.dropped,
                            "messages": recorder.bag.messages, "problem": recorder.error}
    link_of = {n: f"ros2:{ns}" if kind == "ros2" else ns for n, ns in ports.items()}
    write_scene_outputs(args, scene, setups, link_of, run, res)
    for n, a in res["arms"].items():
        c = a["closed_loop"]
        errors = (f"tip error mean {c['mean_mm']:.3f} mm, max {c['max_mm']:.3f} mm over {c['cycles']} cycles "
                  f"({c['errors_from']} vs desired)" if c["cycles"] else "no trajectory cycle ran")
        print(f"servo --scene arm {n} ({a['walk']}, {trajs[n].duration:.1f} s, link {kind} {link_of[n]}): {errors}")
    stopped = {n: o for n, o in run.outcomes.items() if o.stopped}
    if not stopped:
        return 0
    what = "; ".join(f"arm {n} at t = {o.t_stop:.2f} s: {o.stopped} ("
                     f"{'held and disabled' if not o.close_error else o.close_error})" for n, o in stopped.items())
    print(f"wristmark servo: error: stopped safely: {what}", file=sys.stderr)
    return 130 if any(o.cause == "interrupted" for o in stopped.values()) else 3


def scene_namespaces(namespace: str, names: list[str]) -> dict[str, str]:
    """``--ros2 NS``: each arm's ROS 2 namespace ``/NS/NAME`` (InputError, one line, for an arm name
    ROS 2 refuses)."""
    from wristmark.rig.ros2.scene_bridge import arm_namespace

    out = {}
    for n in names:
        try:
            out[n] = arm_namespace(namespace, n)
        except ValueError as e:
            raise InputError(f"--ros2: arm '{n}' cannot name a ROS 2 namespace: {e}") from None
    return out


def check_own_topics(published: dict[str, str], drivers: dict[str, str]) -> None:
    """``--ros2 NS`` with ``--actuator NAME=ros2:NS``: no arm's published namespace is an arm
    driver's (the loop would read its own measured_js back as the arm's; InputError, one line)."""
    for n, ns in published.items():
        other = next((m for m, d in drivers.items() if d == ns), None)
        if other is not None:
            raise InputError(f"--ros2: arm '{n}' would publish on {ns}, arm '{other}''s --actuator namespace (the loop "
                             "would read its own measured_js back as the arm's): pick another --ros2 NS")


def arm_cycle_hook(view: Any, bridges: Any) -> Any:
    """The scene loop's ``on_cycle(arm, record)``: the live view's and the ROS 2 bridges' (None: neither)."""
    hooks = [h for h in (None if view is None else view.on_arm_cycle,
                         None if bridges is None else bridges.on_cycle) if h is not None]
    if len(hooks) <= 1:
        return hooks[0] if hooks else None

    def hook(arm: str, rec: Any) -> None:
        for h in hooks:
            h(arm, rec)

    return hook


@dataclasses.dataclass(frozen=True)
class SceneArms:
    """A hardware scene as the live view sees it (viz.arms_scene.ArmsSetup): each arm's loop setup,
    its base pose in the scene's {w} and the scene camera (``world_T_left`` in the scene's {w})."""

    arms: dict[str, Any]
    camera: Any
    bases: dict[str, Any]

    @property
    def names(self) -> list[str]:
        """The arms' names, in the scene's order."""
        return list(self.arms)

    def base(self, name: str) -> Any:
        """Arm ``name``'s {w} in the scene's {w} (4x4 [m])."""
        return self.bases[name]


def start_scene_view(setups: dict[str, Any], scene_camera: Any, bases: dict[str, Any], host: str | None
                     ) -> tuple[Any, str]:
    """``--view``: the Meshcat live view of every arm (viz.live.start_scene_live_view; loopback
    only unless ``host``) and the lines it has for stderr (its URL), or a one-line error when it
    cannot start."""
    try:
        from wristmark.viz.live import start_scene_live_view
    except ImportError as e:
        raise InputError(f"--view needs the Meshcat live view (viz/live.py), which is not available: {e}") from None
    lines = io.StringIO()
    view = start_scene_live_view(SceneArms(dict(setups), scene_camera, dict(bases)), host=host, stream=lines)
    return view, lines.getvalue()


def load_scene_models(specs: Any, names: list[str], setups: dict[str, Any]) -> dict[str, str]:
    """``--model NAME=MODEL.yaml`` per arm (not every arm needs one): each arm's identified model
    (models.model_file, checked against its arm's segments and actuators) put in its setup;
    returns {arm: path}. InputError/ConfigError (one line) for a bad spec or file."""
    from wristmark.models.arm_spec import ArmSpec, arm_size
    from wristmark.models.model_file import load_model
    from wristmark.rig.loop.arm_set_session import named_specs

    paths = named_specs("--model", specs, names, "model is NAME=MODEL.yaml")
    for n, path in paths.items():
        params = setups[n].params
        segments = len(params.segments) if isinstance(params, ArmSpec) else 2
        try:
            model = load_model(path).for_arm(segments, arm_size(params)[1], path)
        except (InputError, WristmarkError) as e:
            raise type(e)(f"--model {n}={path}: {e}") from None
        setups[n] = setups[n].with_changes(model=model)
    return paths


def open_scene_recorder(args: argparse.Namespace, setups: dict[str, Any], scene_camera: Any, session: Any) -> Any:
    """The ``--record`` bag of every arm (after the boxes and the camera opened, before any
    motion; rig.recording.servo_recorder); closes the session when the bag cannot be written."""
    if not args.record:
        return None
    from wristmark.rig.recording.servo_recorder import ServoRecorder

    try:
        return ServoRecorder(args.record, {n: s.params for n, s in setups.items()}, jpeg=args.record_jpeg,
                             world_T_left=scene_camera.T_world_left)
    except BaseException:
        session.close()
        raise


def scene_result(args: argparse.Namespace, scene: Any, setups: dict[str, Any], trajs: dict[str, Any], session: Any,
                 run: Any, hold: tuple[str, ...]) -> dict[str, Any]:
    """The result JSON: per arm the one-arm servo's fields (rig.loop.servo_summary.summarize) and
    its walk, and the clearance kept between the arms' model bodies [mm]."""
    from wristmark.rig.loop.servo_summary import summarize
    from wristmark.rig.targets.live_target import LiveTrajectory

    arms = {}
    for n, s in setups.items():
        view = session.sensor.view(n, np.asarray(s.host_camera.T_world_left, float))
        walk = trajs[n].kind if isinstance(trajs[n], LiveTrajectory) else args.trajectory or "cube"
        arms[n] = {"walk": "hold" if n in hold else walk,
                   **summarize(s, trajs[n], session.arm_session(n, view), run.outcomes[n])}
    least = run.least_model_distance_m
    return {
        "command": "servo", "scene": scene.source, "camera": args.camera, "arms": arms,
        "clearance": {"required_mm": 1000 * scene.clearance, "margin_mm": 1000 * scene.clearance_margin,
                      "least_model_mm": 1000 * least if np.isfinite(least) else None},
        "tracking_ms_median": float(np.median(run.tracking_ms)) if run.tracking_ms else None,
        "tracking_late": session.sensor.late,  # frames whose tracking outlasted rig tracking_budget (every arm lost)
        "stopped": {n: o.stopped for n, o in run.outcomes.items() if o.stopped},
    }


def write_scene_outputs(args: argparse.Namespace, scene: Any, setups: dict[str, Any], ports: dict[str, str],
                        run: Any, res: dict[str, Any]) -> None:
    """DIR/config.json, DIR/log_<arm>.csv, DIR/result.json (--out) and the result JSON (--json)."""
    from wristmark.rig.recording.run_log import write_json

    if args.out:
        out_dir = Path(args.out)
        out_dir.mkdir(parents=True, exist_ok=True)
        write_json(out_dir / "config.json", {
            "command": "servo", "scene": scene.source, "camera": args.camera,
            "arms": {a.name: {"base": a.base.tolist(),
                              ("actuator" if ports[a.name].startswith("ros2:") else "serial"): ports[a.name],
                              **setups[a.name].describe()}
                     for a in scene.arms}})
        for n, out in run.outcomes.items():
            out.log.write_csv(out_dir / f"log_{n}.csv")
        write_json(out_dir / "result.json", {**res, "run_dir": str(out_dir)})
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, res)

