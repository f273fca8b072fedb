"""``wristmark fk``: tip, marker pose and 6x6 Jacobian in {w} for a configuration psi."""

from __future__ import annotations

import argparse
import json

from wristmark.cli.common_options import add_config_option, add_json_flag, set_example
from wristmark.cli.option_types import PSI_ABS_MAX, float_in
from wristmark.models.kinematics import check_psi, forward_kinematics, tip_jacobian
from wristmark.models.robot_params import RobotParams


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--psi", nargs=6, type=float_in(-PSI_ABS_MAX, PSI_ABS_MAX), required=True,
                   metavar=("PHI", "D", "THETA1", "DELTA1", "THETA2", "DELTA2"),
                   help="configuration [rad, m, rad, rad, rad, rad]")
    add_config_option(p, "--robot")
    add_json_flag(p, "the tip, the marker pose and the Jacobian")
    set_example(p, "wristmark fk --psi 0 0.04 0.7 0 0.9 0 --json")


def run(args: argparse.Namespace) -> int:
    params = RobotParams.load(args.robot) if args.robot else RobotParams()
    psi = check_psi(args.psi)
    fr = forward_kinematics(params, psi)
    J = tip_jacobian(params, psi, fr)
    out = {
        "tip": fr.tip.tolist(),
        "marker": {"R": fr.T_world_marker[:3, :3].tolist(), "t": fr.T_world_marker[:3, 3].tolist()},
        "jacobian": J.tolist(),
    }
    if args.json:
        print(json.dumps(out))
    else:
        x, y, z = (1000 * fr.tip).tolist()
        print(f"tip in {{w}}: [{x:.3f}, {y:.3f}, {z:.3f}] mm")
    return 0
