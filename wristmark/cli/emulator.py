"""``wristmark emulator --pty [--camera-port PORT]``: the simulated bench as a lab.

``--pty`` serves the actuator-box emulator (driving the simulated true arm on the wall clock) on a
new pseudo-terminal and prints its path as the first line of stdout. It plays the arm of
``--robot``: protocol v1 (6 actuators) for the reference arm's flat robot file (the default),
protocol v2 with the arm's n actuators for a format-2 file; the simulated true arm is
sim/plant.py's, with the arm's own plant file (``<name>_plant.yaml`` beside it) unless ``--plant``.
``--camera-port PORT`` makes it the virtual lab (:mod:`sim.virtual_lab`): the same process also
plays the stereo endoscope, rendering its true arm at up to ``--fps`` frames per second and
serving them side by side as an MJPEG stream on 127.0.0.1:PORT (0: any free port), whose URL is
the second line of stdout. Both lines are flushed at once; it serves until SIGINT / SIGTERM.
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.common_options import add_config_option, add_force_argument, set_example
from wristmark.cli.option_types import MAX_TIMEOUT_S, PSI_ABS_MAX, float_in, int_in, positive_float, seed_int
from wristmark.cli.stop_flag import StopFlag, stop_on_signals
from wristmark.cvs.camera import StereoCamera
from wristmark.models.arm_spec import Arm, arm_size, home_psi, load_loop_arm
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError, WristmarkError
from wristmark.models.kinematics import check_psi
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams

DEFAULT_PLANT = default_config("plant.yaml")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--pty", action="store_true", help="serve on a new pseudo-terminal (the serial transport)")
    p.add_argument("--ros2", nargs="?", const="lab", metavar="NS",
                   help="instead of --pty: the virtual lab over ROS 2 (NS/servo_jp, NS/crtk_command, NS/measured_js, "
                        "and the endoscope on NS/{left,right}/image_raw/compressed; loopback unless CYCLONEDDS_URI "
                        "says otherwise; default NS lab; docs/ros2.md); with --scene each arm under NS/NAME, one "
                        "endoscope under NS")
    add_config_option(p, "--plant")
    add_config_option(p, "--robot")
    p.add_argument("--scene", metavar="SCENE.yaml",
                   help="several arms in one view (a scene file, e.g. configs/scenes/two_arms.yaml): one actuator "
                        "box per arm, each on its own new pty, and one endoscope rendering them all; with --pty "
                        "--camera-port (stdout: one line 'NAME PTY' per arm in the scene's order, then the stream URL) "
                        "or --ros2 [NS] (one line 'NAME ros2:/NS/NAME' per arm, then the camera's ros2:LEFT,RIGHT)")
    p.add_argument("--watchdog", type=positive_float(MAX_TIMEOUT_S), default=0.25, metavar="S",
                   help="watchdog timeout [s] (default 0.25, as protocol v1 specifies)")
    p.add_argument("--psi0", nargs="+", type=float_in(-PSI_ABS_MAX, PSI_ABS_MAX), metavar="X",
                   help="initial configuration, one value per configuration variable of the arm (default: home)")
    p.add_argument("--rt-priority", type=int_in(1, 99), metavar="N",
                   help="run every thread (serving, and with --camera-port rendering and streaming) under "
                        "SCHED_FIFO at priority N, as firmware and a camera are not starved by other work "
                        "(needs root or CAP_SYS_NICE); the actuator box's thread runs at N + 1")
    p.add_argument("--render-normal-priority", action="store_true",
                   help="with --rt-priority and --camera-port: render at normal priority (only the box and the "
                        "stream in real time), for a renderer that needs every core")
    cam = p.add_argument_group("virtual endoscope (with --camera-port)")
    cam.add_argument("--camera-port", type=int_in(0, 65535), metavar="PORT",
                     help="also play the stereo endoscope: an MJPEG stream on 127.0.0.1:PORT (0: any free port)")
    cam.add_argument("--fps", type=positive_float(1000.0), default=30.0, metavar="F",
                     help="frames per second at most (default 30; fewer where rendering cannot keep up)")
    cam.add_argument("--truth-out", metavar="CSV",
                     help="log each frame's capture time and true tip (t,tip_x,tip_y,tip_z)")
    cam.add_argument("--truth-dense-out", metavar="CSV",
                     help="also log the true tip every ~4 ms of the box's clock (same columns), for errors "
                          "evaluated at any instant rather than interpolated between frames")
    cam.add_argument("--image-scale", type=float_in(0.05, 1.0), default=1.0, metavar="F",
                     help="render at F x the calibrated size (default 1)")
    add_config_option(cam, "--calib", note="the endoscope's calibration and pose; default configs/camera.yaml, "
                      "placed for another arm to frame its workspace as the simulated bench does")
    cam.add_argument("--calib-out", metavar="YAML",
                     help="write the calibration the host must use (the endoscope as the lab believes it placed: "
                          "pass it to 'wristmark servo --calib'); with --camera-port or --ros2")
    add_config_option(cam, "--marker")
    cam.add_argument("--jpeg-quality", type=int_in(1, 100), default=90, metavar="Q", help="JPEG quality (default 90)")
    cam.add_argument("--seed", type=seed_int(), default=0, help="render noise seed (default 0)")
    cam.add_argument("--loads-from-stdin", action="store_true",
                     help="read lines 'load FX FY FZ' on stdin: a known tip force [N] in {w} hung on the arm on top "
                          "of the plant's own ('load 0 0 0' takes it off); the weight of identify --load")
    add_force_argument(p)
    set_example(p, "wristmark emulator --pty", "wristmark emulator --pty --robot configs/robots/tendon3.yaml",
                "wristmark emulator --pty --camera-port 0 --fps 30 --image-scale 0.35 "
                "--truth-out truth.csv",
                "wristmark emulator --scene configs/scenes/two_arms.yaml --pty --camera-port 0 --image-scale 0.35 "
                "--truth-out truth.csv --calib-out lab_calib.yaml")


def _camera_options_without_port(args: argparse.Namespace) -> list[str]:
    given = [("--fps", args.fps != 30.0), ("--truth-out", args.truth_out), ("--truth-dense-out", args.truth_dense_out),
             ("--image-scale", args.image_scale != 1.0),
             ("--calib", args.calib), ("--calib-out", args.calib_out), ("--marker", args.marker),
             ("--render-normal-priority", args.render_normal_priority), ("--loads-from-stdin", args.loads_from_stdin)]
    return [name for name, set_ in given if set_]


def run(args: argparse.Namespace) -> int:
    from wristmark.sim.actuator_emulator import ActuatorEmulator
    from wristmark.sim.plant import TruePlant
    from wristmark.sim.plant_params import PlantParams
    from wristmark.sim.setup import arm_plant_file

    if args.scene is not None:
        return _run_scene(args)
    if args.ros2 is not None:
        _check_ros2_options(args)
    elif not args.pty:
        raise InputError("pass --pty (the actuator box on a pseudo-terminal) or --ros2 [NS] (the lab over ROS 2)")
    if not args.watchdog > 0:
        raise InputError(f"--watchdog must be > 0 s, got {args.watchdog}")
    if args.camera_port is None and args.ros2 is None and _camera_options_without_port(args):
        raise InputError(f"{', '.join(_camera_options_without_port(args))} need --camera-port PORT")
    if args.render_normal_priority and args.rt_priority is None:
        raise InputError("--render-normal-priority needs --rt-priority N")
    from wristmark.rig.recording.output_dir import claim_outputs

    # before anything is served
    claim_outputs(files=[args.truth_out, args.truth_dense_out, args.calib_out], force=args.force)
    params = load_loop_arm(args.robot, MarkerModel.load(args.marker or default_config("marker.yaml")))
    n = arm_size(params)[0]
    plant_path = Path(args.plant) if args.plant else arm_plant_file(args.robot) or DEFAULT_PLANT
    plant = PlantParams.load(plant_path) if plant_path.exists() or args.plant else PlantParams()
    if args.psi0 is not None and len(args.psi0) != n:
        raise InputError(f"--psi0 needs {n} values (one per configuration variable of the arm), got {len(args.psi0)}")
    psi0 = np.array(args.psi0 if args.psi0 else (HOME_PSI if isinstance(params, RobotParams) else home_psi(params)),
                    dtype=float)
    try:
        check_psi(psi0, params)
        TruePlant(params, plant, psi0=psi0)  # the plant file fits the arm: one line before anything is served
    except WristmarkError as e:
        raise InputError(str(e)) from None
    done = stop_on_signals()
    if args.ros2 is not None:
        return _serve_ros2_lab(args, params, plant, psi0, done)
    if args.camera_port is None:
        if args.rt_priority is not None:
            from wristmark.rig.loop.realtime_priority import request_realtime_priority

            request_realtime_priority(args.rt_priority)  # the serving thread inherits it
        emulator = ActuatorEmulator(TruePlant(params, plant, psi0=psi0), params, watchdog_s=args.watchdog)
        path = emulator.serve_pty()
        print(path, flush=True)
        print(f"actuator emulator (protocol v{emulator.protocol_version}, {emulator.count} actuators, "
              f"watchdog {args.watchdog * 1000:.0f} ms) on {path}; "
              "Ctrl-C to stop", file=sys.stderr, flush=True)
        while not done.wait(0.2):
            pass
        emulator.stop()
        return 0
    return _serve_lab(args, params, plant, psi0, done)


def lab_calibration(args: argparse.Namespace, params: Arm, marker: MarkerModel) -> StereoCamera:
    """The lab's endoscope as the host is to believe it (before the plant's ``camera_offset``):
    ``--calib``, else configs/camera.yaml, which the simulated bench places for another arm than
    the reference one to frame that arm's workspace (sim.setup.camera_for_arm, as ``experiment``
    does); written to ``--calib-out`` when given, for the host's ``--calib``."""
    from wristmark.cvs.calibration.load import load_calibration, save_calibration
    from wristmark.sim.setup import camera_for_arm

    calib = load_calibration(args.calib or default_config("camera.yaml"))
    if not args.calib:
        placed = camera_for_arm(calib, params, marker)
        if placed is not calib and not args.calib_out:
            print("wristmark emulator: the endoscope is placed to frame this arm, not where configs/camera.yaml "
                  "says: --calib-out FILE writes its calibration for the host's --calib", file=sys.stderr, flush=True)
        calib = placed
    if args.calib_out:
        save_calibration(args.calib_out, calib)
    return calib


def _serve_lab(args: argparse.Namespace, params: Arm, plant: object, psi0: np.ndarray,
               done: StopFlag) -> int:
    from wristmark.models.marker import MarkerModel
    from wristmark.rig.loop.heap_freeze import freeze_heap
    from wristmark.rig.loop.loop_setup import default_config
    from wristmark.sim.virtual_lab import LabCamera, VirtualLab

    marker = MarkerModel.load(args.marker or default_config("marker.yaml"))
    calib = lab_calibration(args, params, marker)
    camera = LabCamera(fps=args.fps, image_scale=args.image_scale, seed=args.seed, jpeg_quality=args.jpeg_quality,
                       port=args.camera_port)
    lab = VirtualLab(params, plant, calib, marker, camera, psi0=psi0, watchdog_s=args.watchdog,  # type: ignore[arg-type]
                     truth_out=args.truth_out, truth_dense_out=args.truth_dense_out, rt_priority=args.rt_priority,
                     render_rt=not args.render_normal_priority)
    try:
        path, url = lab.start()
        freeze_heap()  # a full collection would stop the box and the camera for ~0.1 s (rig.loop.heap_freeze)
        print(path, flush=True)
        print(url, flush=True)
        if args.loads_from_stdin:
            threading.Thread(target=_read_loads, args=(sys.stdin, lab.hang), daemon=True,
                             name="wristmark-lab-loads").start()
        w, h = lab.camera.image_size
        print(f"virtual lab: actuator box (protocol v{lab.emulator.protocol_version}, {lab.emulator.count} "
              f"actuators) on {path}; stereo endoscope {2 * w}x{h} side by side at "
              f"up to {args.fps:g} fps on {url}; Ctrl-C to stop", file=sys.stderr, flush=True)
        return _serve_until_done(lab, done)
    finally:
        _stop_and_report(lab)


def _stop_and_report(lab: Any) -> None:
    """Stop the lab and say on stderr what its camera did."""
    lab.stop()
    s = lab.stats.summary()
    print(f"virtual lab: {s['frames']} frames at {s['fps'] or 0:.1f} fps (render {s['render_ms_median'] or 0:.1f} ms, "
          f"JPEG {s['encode_ms_median'] or 0:.1f} ms median)", file=sys.stderr, flush=True)


def _serve_until_done(lab: Any, done: StopFlag) -> int:
    """Serve until ``done`` (0), or 1 with one line on stderr when the lab's camera failed."""
    while not done.wait(0.2):
        if lab.error:
            print(f"wristmark emulator: error: {lab.error}", file=sys.stderr, flush=True)
            return 1
    return 0


def _serve_ros2_lab(args: argparse.Namespace, params: Arm, plant: object, psi0: np.ndarray,
                    done: StopFlag) -> int:
    """The virtual lab over ROS 2 (sim/ros2_lab.py): stdout's first line the ``--actuator`` SPEC
    (ros2:/NS), its second the ``--camera`` SPEC (ros2:LEFT,RIGHT)."""
    from wristmark.rig.ros2.bridge import clean_namespace
    from wristmark.rig.ros2.dds_config import require_cyclonedds
    from wristmark.sim.ros2_lab import Ros2Lab

    try:
        ns = clean_namespace(args.ros2)
    except ValueError as e:
        raise InputError(f"--ros2: {e}") from None
    require_cyclonedds("--ros2")
    marker = MarkerModel.load(args.marker or default_config("marker.yaml"))
    calib = lab_calibration(args, params, marker)
    lab = Ros2Lab(params, plant, calib, marker, namespace=ns, fps=args.fps, image_scale=args.image_scale,  # type: ignore[arg-type]
                  seed=args.seed, jpeg_quality=args.jpeg_quality, watchdog_s=args.watchdog, truth_out=args.truth_out,
                  psi0=psi0)
    try:
        lab.start()
        print(f"ros2:{ns}", flush=True)
        print(f"ros2:{ns}/left/image_raw/compressed,{ns}/right/image_raw/compressed", flush=True)
        w, h = lab.camera.image_size
        print(f"virtual lab over ROS 2: the arm on {ns}/servo_jp, crtk_command, measured_js; stereo endoscope "
              f"{w}x{h} at up to {args.fps:g} fps on {ns}/{{left,right}}/image_raw/compressed; Ctrl-C to stop",
              file=sys.stderr, flush=True)
        while not done.wait(0.2):
            if lab.error:
                print(f"wristmark emulator: error: {lab.error}", file=sys.stderr, flush=True)
                return 1
    finally:
        lab.stop()
    print(f"virtual lab over ROS 2: {lab.frames} frames, {lab.targets} targets, {lab.watchdog_trips} watchdog trips, "
          f"{lab.malformed} malformed messages", file=sys.stderr, flush=True)
    return 0


def _check_ros2_options(args: argparse.Namespace) -> None:
    """``--ros2``: none of the pty lab's options (InputError, one line)."""
    if args.pty or args.camera_port is not None or args.truth_dense_out or args.rt_priority is not None \
            or args.loads_from_stdin or args.render_normal_priority:
        raise InputError("--ros2 serves the arm and the endoscope over ROS 2: no --pty, --camera-port, "
                         "--truth-dense-out, --rt-priority, --render-normal-priority or --loads-from-stdin")


SCENE_REFUSED = (("--robot", "robot"), ("--plant", "plant"), ("--marker", "marker"),
                 ("--calib", "calib"), ("--psi0", "psi0"), ("--truth-dense-out", "truth_dense_out"),
                 ("--loads-from-stdin", "loads_from_stdin"))


def _run_scene(args: argparse.Namespace) -> int:
    """``--scene``: the virtual lab of several arms (sim.scene_lab); stdout one line ``NAME PTY``
    per arm in the scene's order, then the stream URL, each flushed at once."""
    given = [opt for opt, key in SCENE_REFUSED if getattr(args, key, None) not in (None, False)]
    if given:
        raise InputError(f"{', '.join(given)}: not with --scene (each arm's robot, plant and marker files are named in "
                         "the scene file; the endoscope is the scene's)")
    if args.ros2 is not None:
        _check_ros2_options(args)
        return _serve_ros2_scene(args)
    if not args.pty or args.camera_port is None:
        raise InputError("--scene needs --pty and --camera-port PORT (one box per arm on its own pty, one endoscope) "
                         "or --ros2 [NS] (each arm and the endoscope over ROS 2)")
    if args.render_normal_priority and args.rt_priority is None:
        raise InputError("--render-normal-priority needs --rt-priority N")
    from wristmark.rig.loop.heap_freeze import freeze_heap
    from wristmark.rig.recording.output_dir import claim_outputs
    from wristmark.sim.scene_lab import SceneLab
    from wristmark.sim.scene_setup import load_scene_setup
    from wristmark.sim.virtual_lab import LabCamera

    claim_outputs(files=[args.truth_out, args.calib_out], force=args.force)  # before anything is served
    setup = load_scene_setup(args.scene)
    camera = LabCamera(fps=args.fps, image_scale=args.image_scale, seed=args.seed, jpeg_quality=args.jpeg_quality,
                       port=args.camera_port)
    lab = SceneLab(setup, camera, watchdog_s=args.watchdog, truth_out=args.truth_out, rt_priority=args.rt_priority,
                   render_rt=not args.render_normal_priority)
    _write_scene_calibration(args, setup)
    done = stop_on_signals()
    try:
        ptys, url = lab.start()
        freeze_heap()  # a full collection would stop the boxes and the camera for ~0.1 s (rig.loop.heap_freeze)
        for name, path in ptys.items():
            print(f"{name} {path}", flush=True)
        print(url, flush=True)
        w, h = lab.camera.image_size
        boxes = ", ".join(f"{n} (protocol v{lab.emulators[n].protocol_version}, {lab.emulators[n].count} actuators) "
                          f"on {p}" for n, p in ptys.items())
        print(f"virtual lab of {setup.scene.source}: actuator boxes {boxes}; stereo endoscope {2 * w}x{h} side by "
              f"side at up to {args.fps:g} fps on {url}; Ctrl-C to stop", file=sys.stderr, flush=True)
        return _serve_until_done(lab, done)
    finally:
        _stop_and_report(lab)


def _write_scene_calibration(args: argparse.Namespace, setup: Any) -> None:
    """``--calib-out``: the endoscope as the scene's lab placed it (world_T_left in the scene's {w},
    the host's ``--calib``); without it a line on stderr saying so."""
    from wristmark.cvs.calibration.load import save_calibration

    if args.calib_out:
        save_calibration(args.calib_out, setup.camera)
    else:
        print("wristmark emulator: the scene's endoscope is placed to frame every arm: --calib-out FILE writes its "
              "calibration for the host's --calib", file=sys.stderr, flush=True)


def _serve_ros2_scene(args: argparse.Namespace) -> int:
    """``--scene --ros2 [NS]``: the scene's virtual lab over ROS 2 (sim.ros2_scene_lab); stdout one
    line ``NAME ros2:/NS/NAME`` per arm in the scene's order (its ``--actuator`` SPEC), then the
    ``--camera`` SPEC (``ros2:LEFT,RIGHT``), each flushed at once."""
    from wristmark.rig.recording.output_dir import claim_outputs
    from wristmark.rig.ros2.bridge import check_namespace_option
    from wristmark.sim.ros2_scene_lab import Ros2SceneLab
    from wristmark.sim.scene_setup import load_scene_setup

    check_namespace_option(args.ros2)
    claim_outputs(files=[args.truth_out, args.calib_out], force=args.force)  # before anything is served
    setup = load_scene_setup(args.scene)
    try:
        lab = Ros2SceneLab(setup, namespace=args.ros2, fps=args.fps, image_scale=args.image_scale, seed=args.seed,
                           jpeg_quality=args.jpeg_quality, watchdog_s=args.watchdog, truth_out=args.truth_out)
    except ValueError as e:  # an arm's name that is no ROS 2 name
        raise InputError(f"--ros2: {e}") from None
    _write_scene_calibration(args, setup)
    done = stop_on_signals()
    try:
        lab.start()
        specs = lab.topics()
        for n in lab.names:
            print(f"{n} {specs[n]}", flush=True)
        print(specs["camera"], flush=True)
        w, h = lab.camera.image_size
        print(f"virtual lab of {setup.scene.source} over ROS 2: each arm on {lab.namespace}/NAME/servo_jp, "
              f"crtk_command, measured_js, operating_state; stereo endoscope {w}x{h} at up to {args.fps:g} fps on "
              f"{lab.namespace}/{{left,right}}/image_raw/compressed; Ctrl-C to stop", file=sys.stderr, flush=True)
        code = _serve_until_done(lab, done)
    finally:
        lab.stop()
    print(f"virtual lab over ROS 2: {lab.endoscope.frames} frames, {lab.count('targets')} targets, "
          f"{lab.count('watchdog_trips')} watchdog trips, {lab.count('malformed')} malformed messages",
          file=sys.stderr, flush=True)
    return code


def _read_loads(lines: Iterable[str], hang: Callable[[np.ndarray], None]) -> None:
    """Hang each ``load FX FY FZ`` line's force [N] in {w} on the lab's arm; a line that is not
    one is reported on stderr in one line and changes nothing."""
    for line in lines:
        words = line.split()
        if not words:
            continue
        try:
            if words[0] != "load" or len(words) != 4:
                raise ValueError("want 'load FX FY FZ' (newton, in {w})")
            force = np.array([float(w) for w in words[1:]])
            if not np.all(np.isfinite(force)) or np.linalg.norm(force) > 10.0:
                raise ValueError("a finite force of at most 10 N")
        except ValueError as e:
            print(f"wristmark emulator: ignored {line.strip()!r}: {e}", file=sys.stderr, flush=True)
            continue
        hang(force)
        print(f"virtual lab: a tip load of {np.linalg.norm(force):.4g} N hangs on the arm "
              f"({force[0]:.4g}, {force[1]:.4g}, {force[2]:.4g} in {{w}})", file=sys.stderr, flush=True)
