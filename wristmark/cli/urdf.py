"""``wristmark urdf``: write the pseudo-rigid URDF of the arm (stem joints + chord segments); any arm
with a format-2 robot file (docs/your-arm.md)."""

from __future__ import annotations

import argparse
import json

from wristmark.cli.common_options import add_config_option, add_force_argument, add_json_flag, set_example
from wristmark.cli.option_types import MAX_LINKS, int_in
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="FILE.urdf", help="output file: the URDF to write")
    p.add_argument(
        "--links",
        type=int_in(1, MAX_LINKS),
        default=8,
        metavar="N",
        help="pseudo-rigid links per segment (default 8; exact for every N)",
    )
    add_config_option(p, "--robot")
    add_config_option(p, "--marker")
    add_json_flag(p, "a summary")
    set_example(p, "wristmark urdf --out runs/tour/arm.urdf --links 8")
    add_force_argument(p)


def run(args: argparse.Namespace) -> int:
    from wristmark.models.arm_spec import load_arm, robot_file_format
    from wristmark.models.arm_urdf import write_arm_urdf
    from wristmark.models.marker import MarkerModel
    from wristmark.models.robot_params import load_robot
    from wristmark.models.urdf import write_urdf

    if args.links < 1:
        raise InputError(f"--links must be >= 1, got {args.links}")
    marker = MarkerModel.load(args.marker) if args.marker else None
    if args.robot and robot_file_format(args.robot) == 2:  # any arm (docs/your-arm.md)
        spec = load_arm(args.robot, marker or MarkerModel())
        claim_outputs(files=[args.out], force=args.force)
        path = write_arm_urdf(args.out, spec, args.links, marker)
    else:
        params = load_robot(args.robot, marker or MarkerModel())
        claim_outputs(files=[args.out], force=args.force)
        path = write_urdf(args.out, params, args.links, marker)
    if args.json:
        print(json.dumps({"urdf": str(path), "links_per_segment": args.links}))
    else:
        print(f"wrote {path} ({args.links} links per segment)")
    return 0
