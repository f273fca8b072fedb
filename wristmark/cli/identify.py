"""``wristmark identify``: move the arm through an excitation, track the marker and fit how the
real arm differs from its robot file (docs/identification.md; docs/design.md "Identification (know your arm)").

Sources: the simulated bench (default, in process: ``--plant P`` is the true arm, never shown to
the fit), hardware or the virtual lab (``--serial PORT --camera SPEC --calib CALIB``: the same
serial link and threaded frame feed as ``wristmark servo``, rig/loop/hardware_session.py), or
``--from-log DIR`` (an excitation recorded with ``--log DIR``: DIR/excitation.npz; or a servo
run's folder, ``servo``/``experiment --out RUN``: RUN/log.csv, rig/recording/run_excitation.py).
Writes MODEL.yaml (``--out``: the plant-file keys with the fitted values, ``rms_m``, ``poses``
and the fit's report), a summary on stderr and ``--json`` on stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.common_options import add_config_option, add_force_argument, add_json_flag, set_example
from wristmark.cli.option_types import MAX_IMAGE_SCALE, MIN_IMAGE_SCALE, finite_float, float_in, int_in, seed_int
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs

LOG_FILE = "excitation.npz"
DATA_KEYS = ("times", "encoders", "targets", "sample_index", "tips", "psi_hint")
OPTIONAL_KEYS = ("loads",)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="FILE.yaml", help="output file: the identified arm (MODEL.yaml)")
    add_force_argument(p)
    p.add_argument("--poses", type=int_in(8, 500), default=24, metavar="N",
                   help="poses of the excitation (each approached from random sides of every play; default 24)")
    add_config_option(p, "--robot")
    add_config_option(p, "--plant")
    add_config_option(p, "--calib")
    add_config_option(p, "--marker")
    add_config_option(p, "--registration")
    p.add_argument("--rig", metavar="YAML", help="rig/loop file (default configs/rig.yaml)")
    p.add_argument("--sensor", choices=("vision", "truth-noise"),
                   help="simulated bench: rendered images + tracker (default) or truth+noise (fast)")
    p.add_argument("--load", type=float_in(0.0, 1.0), default=0.0, metavar="N",
                   help="hang a known N newton weight on the tip, so that the segments' stiffness is fitted too "
                        "(default 0: none): on the simulated bench at every other pose; on hardware for the "
                        "second half of the poses, where identify asks you to hang it and waits for Enter")
    p.add_argument("--load-direction", type=finite_float(), nargs=3, default=(0.0, 0.0, -1.0),
                   metavar=("DX", "DY", "DZ"),
                   help="where the weight pulls, in {w} (gravity; default 0 0 -1: -z_w)")
    p.add_argument("--seed", type=seed_int(), help="pose choice and render noise seed (default the rig's)")
    p.add_argument("--serial", metavar="PORT", help="hardware / virtual lab: the actuator box's serial port")
    p.add_argument("--camera", metavar="SPEC", help="hardware / virtual lab: the stereo frame source")
    p.add_argument("--rt-priority", type=int_in(1, 99), metavar="N",
                   help="with --serial: run the excitation (and its camera threads) under SCHED_FIFO at priority N, "
                        "so a loaded host keeps feeding the box's watchdog (as servo --rt-priority; needs root or "
                        "CAP_SYS_NICE)")
    p.add_argument("--image-scale", type=float_in(MIN_IMAGE_SCALE, MAX_IMAGE_SCALE), metavar="F",
                   help="images at F x the calibrated size (simulated bench: rendered so; a camera: delivers so)")
    p.add_argument("--from-log", metavar="DIR", help=f"identify offline from DIR/{LOG_FILE} (written by --log) or "
                   "from a servo run's folder (servo/experiment --out DIR: its log.csv)")
    p.add_argument("--log", metavar="DIR", help=f"write the excitation's record to DIR/{LOG_FILE}")
    p.add_argument("--register-out", metavar="REG.yaml",
                   help="also fit where the camera is, from the same excitation, and write it as a registration "
                        "file (world_T_left; the model is then fitted in that frame: use both with --registration "
                        "REG --model MODEL)")
    add_json_flag(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    set_example(p, "wristmark identify --plant configs/plant_unseen.yaml --out model.yaml",
                "wristmark identify --plant configs/plant_unseen.yaml --log idlog --out model.yaml --force",
                "wristmark identify --from-log idlog --out model2.yaml",
                "wristmark identify --from-log runs/latest --out model3.yaml",
                "wristmark identify --plant configs/plant_misplaced_camera.yaml --out model.yaml "
                "--register-out reg.yaml",
                "wristmark identify --serial /dev/pts/3 --camera http://127.0.0.1:41234/stream.mjpg --calib calib.yaml "
                "--registration reg.yaml --image-scale 0.35 --out model.yaml",
                "wristmark identify --serial /dev/pts/3 --camera http://127.0.0.1:41234/stream.mjpg --calib calib.yaml "
                "--registration reg.yaml --image-scale 0.35 --load 0.15 --out model_loaded.yaml")


def _check(args: argparse.Namespace) -> None:
    if args.rt_priority is not None and not args.serial:
        raise InputError("--rt-priority is for the hardware path (--serial); the simulated bench runs in "
                         "simulated time")
    if args.serial or args.camera:
        if not (args.serial and args.camera):
            raise InputError("hardware / the virtual lab needs both --serial PORT and --camera SPEC")
        if args.from_log or args.plant or args.sensor:
            raise InputError("--serial/--camera identify the arm on the port: --from-log, --plant and --sensor "
                             "are for other sources")
        if not args.calib:
            raise InputError("--serial/--camera need --calib CALIB (the stereo calibration of that camera)")
    if args.from_log and (args.plant or args.sensor or args.load):
        raise InputError("--from-log identifies from the record alone: --plant, --sensor and --load are for the "
                         "simulated bench")
    if args.from_log and not any((Path(args.from_log) / f).is_file() for f in (LOG_FILE, "log.csv")):
        raise InputError(f"--from-log: neither {LOG_FILE} (identify --log) nor log.csv (a servo run) in "
                         f"{args.from_log}")


def _load(args: argparse.Namespace) -> Any:
    """The known weight's force [N] in {w} (None without --load)."""
    from wristmark.rig.loop.known_load import load_force

    force = load_force(args.load, np.asarray(args.load_direction, float))  # a bad direction: one line, always
    return force if args.load > 0 else None


def _outputs(args: argparse.Namespace) -> list[str]:
    """The files this run writes (refused together when one exists without --force)."""
    return [args.out] + ([args.register_out] if args.register_out else [])


def _load_log(path: Path) -> Any:
    from wristmark.solvers.identification import ExcitationData

    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in DATA_KEYS if k not in z]
            if missing:
                raise InputError(f"{path}: missing {', '.join(missing)}")
            arrays = {k: np.asarray(z[k]) for k in DATA_KEYS + OPTIONAL_KEYS if k in z}
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: not an excitation record ({e})") from None
    f = {k: arrays[k].astype(float) for k in ("times", "encoders", "targets", "tips", "psi_hint")}
    loads = arrays["loads"].astype(float) if "loads" in arrays else None
    return ExcitationData(f["times"], f["encoders"], f["targets"], arrays["sample_index"].astype(int), f["tips"],
                          f["psi_hint"], loads=loads)


def _hardware_setup(args: argparse.Namespace) -> Any:
    """The LoopSetup of the arm on the port (the simulated bench is not imported): world_T_left
    from --registration, else the calibration's; neither is refused."""
    import dataclasses

    from wristmark.rig.loop.loop_setup import load_loop_setup

    setup = load_loop_setup(robot=args.robot, marker=args.marker, camera=args.calib, rig=args.rig,
                            require_world=False)
    if args.registration:
        from wristmark.cvs.calibration.registration_file import load_registration

        setup = setup.with_changes(registration=load_registration(args.registration).world_T_left)
    elif setup.camera.T_world_left is None:
        raise InputError(f"{args.calib}: no world_T_left; identify needs the camera placed in {{w}}: give "
                         "--registration REG (wristmark register) or a calibration that carries it")
    changes = {k: v for k, v in (("image_scale", args.image_scale), ("seed", args.seed)) if v is not None}
    return setup.with_changes(rig=dataclasses.replace(setup.rig, **changes)) if changes else setup


FRAME_WAIT_S = 0.08  # [s] longest wait for a fresh frame at a pose (+ tracking budget: inside the 250 ms watchdog)


def excite_on_hardware(setup: Any, port: str, camera: str, poses: int, progress: bool,
                       force: Any = None, rt_priority: int | None = None) -> Any:
    """Open the actuator box and the camera as ``wristmark servo --serial --camera`` does, run the
    excitation on the wall clock and close (hold, DISABLE) whatever happens. ``force`` [N] in {w}:
    a known weight for the second half of the poses, hung by the person at the bench when asked
    (rig/loop/known_load.py). ``rt_priority``: SCHED_FIFO priority of this thread and the camera's
    (None: normal scheduling)."""
    from tqdm import tqdm

    from wristmark.cvs.tracking.warmup import warm_up
    from wristmark.rig.loop.excitation import excitation_plan, run_excitation
    from wristmark.rig.loop.hardware_session import open_hardware_session
    from wristmark.rig.loop.heap_freeze import freeze_heap
    from wristmark.rig.loop.known_load import KnownLoadPrompt, with_known_load
    from wristmark.rig.loop.servo_session import LinkOptions

    unit = setup.controller.play_max_for(setup.params)
    plan = excitation_plan(setup.params, unit, poses=poses, seed=setup.rig.seed)
    if force is not None:
        plan = with_known_load(plan, force, block=True)
    plan.duration(setup.rig.control_dt, setup.params)  # the ramps' first (slow) calls before the box is enabled
    warm_up()
    if rt_priority is not None:  # before any thread starts: the camera's threads inherit it
        from wristmark.rig.loop.realtime_priority import request_realtime_priority

        request_realtime_priority(rt_priority)
    with open_hardware_session(setup, LinkOptions(kind="serial", port=port), camera) as session:
        freeze_heap()  # no full garbage collection of the start-up heap mid-run (as servo: a silent host trips the box)
        session.start()
        with tqdm(total=poses, desc="identify: excitation", disable=not progress, leave=False) as bar:
            prompt = KnownLoadPrompt(session.link) if force is not None else None
            data = run_excitation(setup.params, session.link, session.frames, session.sensor, plan,
                                  setup.rig.control_dt, on_pose=lambda i: bar.update(1), frame_wait=FRAME_WAIT_S,
                                  apply_load=prompt)
            if prompt is not None:
                print(prompt.instruction(np.zeros(3)) + " (the excitation is over)", file=sys.stderr, flush=True)
    if session.close_error:
        raise InputError(f"{port}: could not confirm hold/disable after the excitation ({session.close_error})")
    seen, wanted = int(np.isfinite(data.tips).all(axis=1).sum()), poses * plan.frames
    if seen < wanted // 4:
        raise InputError(f"{camera}: the marker was tracked in only {seen} of the {wanted} frames at rest wanted "
                         "(camera, calibration, --image-scale or registration wrong?)")
    return data


def run(args: argparse.Namespace) -> int:
    import dataclasses

    if args.serial:
        _check(args)
        force = _load(args)
        claim_outputs(files=_outputs(args), dirs=[], force=args.force)
        setup = _hardware_setup(args)
        data = excite_on_hardware(setup, args.serial, args.camera, args.poses, not args.no_progress, force,
                                  args.rt_priority)
        return _fit_and_write(args, setup, data, f"port {args.serial}, camera {args.camera}")

    from wristmark.sim.identify_bench import bench_plan, excite_on_bench
    from wristmark.sim.setup import load_setup

    _check(args)
    _load(args)
    claim_outputs(files=_outputs(args), dirs=[], force=args.force)
    setup = load_setup(robot=args.robot, marker=args.marker, camera=args.calib, plant=args.plant, rig=args.rig)
    if args.registration:
        from wristmark.cvs.calibration.registration_file import load_registration

        setup = setup.with_changes(registration=load_registration(args.registration).world_T_left)
    rig = setup.rig
    if args.sensor:
        rig = dataclasses.replace(rig, sensor=args.sensor)
    if args.seed is not None:
        rig = dataclasses.replace(rig, seed=args.seed)
    if args.image_scale is not None:
        rig = dataclasses.replace(rig, image_scale=args.image_scale)
    setup = setup.with_changes(rig=rig)
    if args.from_log and (Path(args.from_log) / LOG_FILE).is_file():
        data = _load_log(Path(args.from_log) / LOG_FILE)
        source = f"log {args.from_log}"
    elif args.from_log:
        from wristmark.rig.recording.run_excitation import excitation_from_run

        data = excitation_from_run(args.from_log, setup.params)
        source = f"servo run {args.from_log}"
    else:
        plan = bench_plan(setup, args.poses, load=args.load, direction=tuple(args.load_direction))
        from tqdm import tqdm

        with tqdm(total=args.poses, desc="identify: excitation", disable=args.no_progress, leave=False) as bar:
            data = excite_on_bench(setup, plan, on_pose=lambda i: bar.update(1))
        source = f"simulated bench, plant {setup.sources.get('plant')}"
    return _fit_and_write(args, setup, data, source)


def _fit_and_write(args: argparse.Namespace, setup: Any, data: Any, source: str) -> int:
    """Fit the record, write MODEL.yaml (and --log's record), report."""
    from wristmark.models.model_file import save_model
    from wristmark.solvers.identification import identify

    unit = setup.controller.play_max_for(setup.params)
    if args.log:
        Path(args.log).mkdir(parents=True, exist_ok=True)
        extra = {"loads": data.loads} if data.loads is not None else {}
        np.savez(Path(args.log) / LOG_FILE, **{k: getattr(data, k) for k in DATA_KEYS}, **extra)
    ident = identify(setup.params, data, unit, camera=bool(args.register_out))
    motion = float(data.times[-1] - data.times[0]) if data.times.size else 0.0
    report: dict[str, Any] = {"rms_m": ident.rms_m, "poses": ident.poses, "excitation_s": motion,
                              "std_errors": ident.std_errors, "not_separable": ident.not_separable,
                              "lag_per_actuator": ident.lag_per_actuator}
    if args.register_out:
        report["registration"] = _write_registration(args.register_out, setup, ident)
    save_model(args.out, ident.plant, report)
    print(f"identify ({source}): {ident.poses} tips over {motion:.1f} s of motion, fit rms "
          f"{1000 * ident.rms_m:.3f} mm -> {args.out}" + (f", {args.register_out}" if args.register_out else ""),
          file=sys.stderr)
    for k, v in ident.values.items():
        print(f"  {k:16s} {v: .6g} +- {ident.std_errors.get(k, float('nan')):.2g}", file=sys.stderr)
    for note in ident.not_separable:
        print(f"  not separable: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps({"model": str(args.out), "values": ident.values, **report}, indent=1))
    return 0


def _write_registration(path: str, setup: Any, ident: Any) -> str:
    """Write the camera the fit found (world_T_left = its correction @ the one the tips were
    measured with) as a registration file; returns the path."""
    from wristmark.cvs.calibration.registration_file import Registration, save_registration

    W = setup.camera.T_world_left
    if W is None or ident.world_correction is None:
        raise InputError("--register-out: no world_T_left to correct (give --calib with one, or --registration)")
    save_registration(path, Registration(ident.world_correction @ np.asarray(W, float), ident.rms_m, ident.poses))
    return str(path)
