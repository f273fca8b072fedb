"""``wristmark identify``: move the arm through an excitation, track the marker and fit how the
real arm differs from its robot file (docs/identification.md; DESIGN.md "Identification").

Sources: the simulated bench (default, in process: ``--plant P`` is the true arm, never shown to
the fit), or ``--from-log DIR`` (an excitation recorded with ``--log DIR``: DIR/excitation.npz).
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
from wristmark.cli.option_types import int_in, seed_int
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs

LOG_FILE = "excitation.npz"
DATA_KEYS = ("times", "encoders", "targets", "sample_index", "tips", "psi_hint")


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
    p.add_argument("--seed", type=seed_int(), help="pose choice and render noise seed (default the rig's)")
    p.add_argument("--serial", metavar="PORT", help="hardware / virtual lab: the actuator box's serial port")
    p.add_argument("--camera", metavar="SPEC", help="hardware / virtual lab: the stereo frame source")
    p.add_argument("--from-log", metavar="DIR", help=f"identify offline from DIR/{LOG_FILE} (written by --log)")
    p.add_argument("--log", metavar="DIR", help=f"write the excitation's record to DIR/{LOG_FILE}")
    add_json_flag(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    set_example(p, "wristmark identify --plant configs/plant_unseen.yaml --out model.yaml",
                "wristmark identify --plant configs/plant_unseen.yaml --log idlog --out model.yaml --force",
                "wristmark identify --from-log idlog --out model2.yaml")


def _check(args: argparse.Namespace) -> None:
    if args.serial or args.camera:
        raise InputError("--serial/--camera: identification on hardware and the virtual lab is not built yet; "
                         "record a servo run or use the simulated bench (--plant)")
    if args.from_log and (args.plant or args.sensor):
        raise InputError("--from-log identifies from the record alone: --plant and --sensor are for the "
                         "simulated bench")
    if args.from_log and not (Path(args.from_log) / LOG_FILE).is_file():
        raise InputError(f"--from-log: no {LOG_FILE} in {args.from_log}")


def _load_log(path: Path) -> Any:
    from wristmark.solvers.identification import ExcitationData

    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in DATA_KEYS if k not in z]
            if missing:
                raise InputError(f"{path}: missing {', '.join(missing)}")
            arrays = {k: np.asarray(z[k]) for k in DATA_KEYS}
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: not an excitation record ({e})") from None
    f = {k: arrays[k].astype(float) for k in ("times", "encoders", "targets", "tips", "psi_hint")}
    return ExcitationData(f["times"], f["encoders"], f["targets"], arrays["sample_index"].astype(int), f["tips"],
                          f["psi_hint"])


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from wristmark.models.model_file import save_model
    from wristmark.sim.identify_bench import bench_plan, excite_on_bench
    from wristmark.sim.setup import load_setup
    from wristmark.solvers.identification import identify

    _check(args)
    claim_outputs(files=[args.out], dirs=[], force=args.force)
    setup = load_setup(robot=args.robot, marker=args.marker, camera=args.calib, plant=args.plant, rig=args.rig)
    if args.registration:
        from wristmark.cvs.calibration.registration_file import load_registration

        setup = setup.with_changes(registration=load_registration(args.registration).world_T_left)
    rig = setup.rig
    if args.sensor:
        rig = dataclasses.replace(rig, sensor=args.sensor)
    if args.seed is not None:
        rig = dataclasses.replace(rig, seed=args.seed)
    setup = setup.with_changes(rig=rig)
    unit = setup.controller.play_max_for(setup.params)
    if args.from_log:
        data = _load_log(Path(args.from_log) / LOG_FILE)
        source = f"log {args.from_log}"
    else:
        plan = bench_plan(setup, args.poses)
        from tqdm import tqdm

        with tqdm(total=args.poses, desc="identify: excitation", disable=args.no_progress, leave=False) as bar:
            data = excite_on_bench(setup, plan, on_pose=lambda i: bar.update(1))
        source = f"simulated bench, plant {setup.sources.get('plant')}"
    if args.log:
        Path(args.log).mkdir(parents=True, exist_ok=True)
        np.savez(Path(args.log) / LOG_FILE, **{k: getattr(data, k) for k in DATA_KEYS})
    ident = identify(setup.params, data, unit)
    motion = float(data.times[-1] - data.times[0]) if data.times.size else 0.0
    report: dict[str, Any] = {"rms_m": ident.rms_m, "poses": ident.poses, "excitation_s": motion,
                              "std_errors": ident.std_errors, "not_separable": ident.not_separable,
                              "lag_per_actuator": ident.lag_per_actuator}
    save_model(args.out, ident.plant, report)
    print(f"identify ({source}): {ident.poses} tips over {motion:.1f} s of motion, fit rms "
          f"{1000 * ident.rms_m:.3f} mm -> {args.out}", file=sys.stderr)
    for k, v in ident.values.items():
        print(f"  {k:16s} {v: .6g} +- {ident.std_errors.get(k, float('nan')):.2g}", file=sys.stderr)
    for note in ident.not_separable:
        print(f"  not separable: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps({"model": str(args.out), "values": ident.values, **report}, indent=1))
    return 0
