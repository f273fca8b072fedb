"""``wristmark urdf``: write the pseudo-rigid URDF of the arm (stem joints + chord segments)."""

from __future__ import annotations

import argparse
import json

from wristmark.cli.option_types import MAX_LINKS, int_in
from wristmark.models.errors import InputError
from wristmark.rig.output_dir import add_force_argument, claim_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="FILE", help="URDF file to write")
    p.add_argument(
        "--links",
        type=int_in(1, MAX_LINKS),
        default=8,
        metavar="N",
        help="pseudo-rigid links per segment (default 8; exact for every N)",
    )
    p.add_argument("--robot", metavar="ROBOT.yaml", help="robot YAML (default: reference robot)")
    p.add_argument("--marker", metavar="MARKER.yaml", help="marker YAML (default: reference)")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    add_force_argument(p)


def run(args: argparse.Namespace) -> int:
    from wristmark.models.marker import MarkerModel
    from wristmark.models.robot_params import load_robot
    from wristmark.models.urdf import write_urdf

    if args.links < 1:
        raise InputError(f"--links must be >= 1, got {args.links}")
    marker = MarkerModel.load(args.marker) if args.marker else None
    params = load_robot(args.robot, marker or MarkerModel())
    claim_outputs(files=[args.out], force=args.force)
    path = write_urdf(args.out, params, args.links, marker)
    if args.json:
        print(json.dumps({"urdf": str(path), "links_per_segment": args.links}))
    else:
        print(f"wrote {path} ({args.links} links per segment)")
    return 0
