"""``wristmark register``: find world_T_left (pose of {ll} in {w}) by moving the arm and tracking
the marker (docs/design.md "Registration").

Sources of observations: the simulated bench (default, in-process: ``--plant P``, whose
``camera_offset`` moves the true camera), ``--serial PORT --camera SPEC`` (hardware or the
virtual lab), or ``--from-log DIR`` (a registration log, rig/registration/log.py). Writes the
registration file (``--out``), per-pose residuals on stderr, ``--json`` on stdout, and with
``--log DIR`` the observations it used.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.common_options import add_config_option, add_force_argument, add_json_flag, set_example
from wristmark.cli.option_types import float_in, int_in, positive_float, seed_int
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams
from wristmark.rig.recording.output_dir import claim_outputs

REPLY_TIMEOUT_S = 0.2  # [s] per attempt at a reply from the actuator box (3 retries)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="FILE.yaml", help="output file: the registration to write")
    add_force_argument(p)
    p.add_argument("--poses", type=int_in(4, 500), default=12, metavar="N",
                   help="configurations to visit (each twice, from either side; default 12)")
    add_config_option(p, "--calib")
    add_config_option(p, "--registration", note="the start of the search")
    add_config_option(p, "--robot")
    add_config_option(p, "--marker")
    add_config_option(p, "--plant")
    p.add_argument("--image-scale", type=positive_float(1.0), metavar="F",
                   help="simulated bench: render at F x the calibrated size")
    p.add_argument("--seed", type=seed_int(), default=0, help="pose choice and render noise seed")
    p.add_argument("--serial", metavar="PORT", help="hardware / virtual lab: the actuator box's serial port")
    p.add_argument("--camera", metavar="SPEC", help="hardware / virtual lab: the stereo frame source")
    p.add_argument("--speed", type=float_in(0.05, 1.0), default=0.5, metavar="F",
                   help="hardware: move at F x the robot's velocity limits (default 0.5)")
    p.add_argument("--from-log", metavar="DIR", help="register offline from DIR/registration_log.csv")
    p.add_argument("--log", metavar="DIR", help="write the observations to DIR/registration_log.csv")
    p.add_argument("--rigid-arm", action="store_true",
                   help="trust the arm model: do not estimate its bend gains, stem coupling and backlash")
    add_json_flag(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    set_example(p, "wristmark register --plant configs/plant_misplaced_camera.yaml --out reg.yaml",
                "wristmark register --serial /dev/ttyACM0 --camera /dev/video0 --calib calib.yaml --out reg.yaml "
                "--log reglog")


def _observe_sim(args: argparse.Namespace, progress: bool) -> tuple[Any, list, dict[str, Any]]:
    import dataclasses

    from wristmark.cvs.calibration.registration_file import load_registration
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.rig.registration.poses import choose_poses
    from wristmark.rig.registration.run import collect
    from wristmark.sim.registration_bench import SimRegistrationRig
    from wristmark.sim.setup import load_setup
    from wristmark.solvers.registration import transform_error

    setup = load_setup(robot=args.robot, marker=args.marker, camera=args.calib, plant=args.plant)
    params = setup.params
    if args.registration:
        setup = setup.with_changes(registration=load_registration(args.registration).world_T_left)
    if args.image_scale is not None:
        setup = setup.with_changes(rig=dataclasses.replace(setup.rig, image_scale=args.image_scale))
    cam = setup.tracking_camera
    poses = choose_poses(setup.params, args.poses, cam, setup.marker, seed=args.seed)
    obs = collect(SimRegistrationRig(setup, seed=args.seed), MarkerTracker(cam, setup.marker), params, poses,
                  cam.T_world_left, progress)
    truth = np.asarray(setup.true_camera.T_world_left, float)
    t, r = transform_error(truth, np.asarray(cam.T_world_left, float))
    extra = {"simulated": True, "true_world_T_left": truth.tolist(),
             "believed_error": {"translation_mm": 1000 * t, "rotation_deg": float(np.degrees(r))}}
    return setup.params, obs, extra


def _observe_hardware(args: argparse.Namespace, progress: bool) -> tuple[Any, list, dict[str, Any]]:
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.calibration.registration_file import apply_registration
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.models.arm_spec import load_loop_arm
    from wristmark.models.marker import MarkerModel
    from wristmark.rig.link.actuator_driver import ActuatorDriver
    from wristmark.rig.registration.hardware import HardwareRegistrationRig
    from wristmark.rig.registration.poses import choose_poses
    from wristmark.rig.registration.run import collect

    if not args.camera:
        raise InputError("--serial needs --camera SPEC (the stereo endoscope's frame source)")
    from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source
    calib = args.calib or str(default_config("camera.yaml"))
    cam = apply_registration(load_calibration(calib), args.registration)
    marker = MarkerModel.load(args.marker) if args.marker else MarkerModel()
    params = load_loop_arm(args.robot, marker)
    poses = choose_poses(params, args.poses, cam, marker, seed=args.seed)
    source = open_stereo_source(args.camera, SourceOptions(image_size=cam.image_size))
    try:
        # registration is not real time: allow a slow box (or a busy virtual lab) 0.2 s per reply
        with ActuatorDriver(args.serial, timeout=REPLY_TIMEOUT_S, retries=3, params=params) as driver:
            rig = HardwareRegistrationRig(driver, source, params, speed=args.speed)
            tracker = MarkerTracker(cam, marker)  # before the first ENABLE: building it takes a while
            try:
                obs = collect(rig, tracker, params, poses, cam.T_world_left, progress)
            finally:
                rig.close()
                for note in rig.notes:
                    print(f"wristmark register: note: {note}", file=sys.stderr)
    finally:
        source.close()
    return params, obs, {"simulated": False}


def arm_summary(params: Any, arm: Any) -> dict[str, Any]:
    """The arm correction fitted alongside, as JSON: the reference arm's keys; any other arm's
    by name (``bend_gain`` and ``plane_offset`` per segment, ``half_play`` per actuator)."""
    out = {"bend_gain": list(arm.bend_gain), "plane_offset_2": arm.plane_offset_2,
           "stem_coupling": arm.stem_coupling, "half_play": list(arm.half_play)}
    if isinstance(params, RobotParams):
        return out
    from wristmark.models.arm_spec import actuator_names

    del out["plane_offset_2"]
    return {**out, "plane_offset": list(arm.plane_offset), "actuators": list(actuator_names(params))}


def run(args: argparse.Namespace) -> int:
    from wristmark.cvs.calibration.registration_file import Registration, save_registration
    from wristmark.cvs.tracking.warmup import warm_up
    from wristmark.models.arm_spec import load_loop_arm, log_psi_names
    from wristmark.models.marker import MarkerModel
    from wristmark.rig.registration.log import read_log, write_log
    from wristmark.rig.registration.run import registration_poses
    from wristmark.solvers.registration import solve_registration, transform_error

    out = Path(args.out)
    if not args.force:  # refuse an existing --out (checked only: written over at the end)
        claim_outputs(files=[out])
    if args.from_log and args.serial:
        raise InputError("give either --from-log DIR or --serial PORT, not both")
    if args.camera and not args.serial:
        raise InputError("--camera SPEC is for hardware: give --serial PORT too (the simulated bench renders its own)")
    warm_up(jit=not args.from_log)  # OpenCV's threads, the tracker's kernels (cvs.tracking.warmup)
    progress = not args.no_progress
    extra: dict[str, Any] = {}
    if args.from_log:
        params = load_loop_arm(args.robot, MarkerModel.load(args.marker) if args.marker else MarkerModel())
        obs = read_log(args.from_log, log_psi_names(params))
    elif args.serial:
        params, obs, extra = _observe_hardware(args, progress)
    else:
        params, obs, extra = _observe_sim(args, progress)
    if args.log:
        write_log(args.log, obs, log_psi_names(params))
    for o in obs:
        if not o.ok:
            print(f"wristmark register: pose {o.pose} ({'-' if o.approach < 0 else '+'}): marker not tracked "
                  f"({o.reason})", file=sys.stderr)
    poses = registration_poses(params, obs)
    res = solve_registration(params, poses, estimate_arm=not args.rigid_arm)
    n_poses = len({o.pose for o in obs if o.ok})
    save_registration(out, Registration(res.world_T_left, res.rms_m, n_poses))
    per_pose = [{"pose": n, "centre_mm": 1000 * float(c), "axis_deg": float(np.degrees(a))}
                for n, c, a in zip(res.names, res.centre_residuals_m, res.axis_residuals_rad)]
    for row in per_pose:
        print(f"wristmark register: {row['pose']}: centre {row['centre_mm']:.3f} mm, axis {row['axis_deg']:.3f} deg",
              file=sys.stderr)
    summary: dict[str, Any] = {
        "out": str(out), "world_T_left": res.world_T_left.tolist(), "rms_m": res.rms_m, "poses": n_poses,
        "visits": len(obs), "per_pose": per_pose, "outliers": res.outliers,
        "arm": arm_summary(params, res.arm), **extra}
    if "true_world_T_left" in extra:
        t, r = transform_error(np.asarray(extra["true_world_T_left"]), res.world_T_left)
        summary["error"] = {"translation_mm": 1000 * t, "rotation_deg": float(np.degrees(r))}
    if args.json:
        print(json.dumps(summary))
    else:
        msg = f"wrote {out}: {n_poses} poses ({len(poses)} tracked visits), centre RMS {1000 * res.rms_m:.3f} mm"
        if "error" in summary:
            msg += (f"; vs the simulated truth {summary['error']['translation_mm']:.3f} mm, "
                    f"{summary['error']['rotation_deg']:.3f} deg")
        print(msg)
    return 0
