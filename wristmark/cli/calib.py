"""``wristmark calib {convert,show}``: read any calibration form of docs/design.md (project YAML,
OpenCV FileStorage, ROS camera_info pair ``LEFT.yaml,RIGHT.yaml``, Kalibr camchain) and write it
as the project's YAML, or print a summary (focal lengths, baseline, field of view, overlap)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from wristmark.cli.common_options import add_config_option, add_force_argument, add_json_flag, set_example
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("action", choices=("convert", "show"), help="convert: write the project's YAML; show: summary")
    add_config_option(p, "--calib", required=True)
    p.add_argument("--out", metavar="FILE.yaml", help="output file (convert): the project's calibration YAML")
    add_force_argument(p)
    add_config_option(p, "--registration")
    add_json_flag(p, "the summary (show)")
    set_example(p, "wristmark calib convert --calib left.yaml,right.yaml --out calib.yaml",
                "wristmark calib show --calib calib.yaml")


def run(args: argparse.Namespace) -> int:
    from wristmark.cvs.calibration.load import load_calibration, save_calibration
    from wristmark.cvs.calibration.registration_file import apply_registration
    from wristmark.cvs.calibration.summary import summarize, summary_text

    cam = apply_registration(load_calibration(args.calib), args.registration)
    if args.action == "convert":
        if not args.out:
            raise InputError("calib convert needs --out C.yaml")
        out = Path(args.out)
        if not args.force:  # refuse an existing --out (checked only: written over at the end)
            claim_outputs(files=[out])
        save_calibration(out, cam)
        print(f"wrote {out}")
        return 0
    s = summarize(cam)
    print(json.dumps(dataclasses.asdict(s)) if args.json else summary_text(s))
    return 0
