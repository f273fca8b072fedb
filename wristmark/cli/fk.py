"""``wristmark fk``: tip, marker pose, 6 x n Jacobian and actuator coordinates in {w} for a
configuration psi of any arm (a format-2 robot file, or the flat reference-arm file)."""

from __future__ import annotations

import argparse
import json

from wristmark.cli.common_options import add_config_option, add_json_flag, set_example
from wristmark.cli.option_types import PSI_ABS_MAX, float_in
from wristmark.models.arm_actuation import arm_actuators
from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian, check_arm_psi
from wristmark.models.arm_spec import ArmSpec, load_arm
from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--psi", nargs="+", type=float_in(-PSI_ABS_MAX, PSI_ABS_MAX), required=True, metavar="Q",
                   help="configuration: the robot's n values in order, its stem joints then theta1, delta1, ... "
                        "[rad or m] (the reference arm: PHI D THETA1 DELTA1 THETA2 DELTA2)")
    add_config_option(p, "--robot", note="a format-2 file describes any arm (docs/your-arm.md)")
    add_json_flag(p, "the tip, the marker pose, the Jacobian and the actuator coordinates")
    set_example(p, "wristmark fk --psi 0 0.04 0.7 0 0.9 0 --json",
                "wristmark fk --robot configs/robots/tendon3.yaml --psi 0.03 0.5 0 0.4 1.0 0.3 -2 --json")


def run(args: argparse.Namespace) -> int:
    spec = load_arm(args.robot) if args.robot else ArmSpec.from_params(RobotParams())
    if len(args.psi) != spec.n:
        raise InputError(f"argument --psi: expected {spec.n} arguments ({' '.join(spec.names)}) for "
                         f"{args.robot or 'the reference arm'}, got {len(args.psi)}")
    psi = check_arm_psi(spec, args.psi)
    fr = arm_frames(spec, psi)
    J = arm_tip_jacobian(spec, psi, fr)
    out = {
        "tip": fr.tip.tolist(),
        "marker": {"R": fr.T_world_marker[:3, :3].tolist(), "t": fr.T_world_marker[:3, 3].tolist()},
        "jacobian": J.tolist(),
        "actuators": arm_actuators(spec, psi).tolist(),
    }
    if args.json:
        print(json.dumps(out))
    else:
        x, y, z = (1000 * fr.tip).tolist()
        print(f"tip in {{w}}: [{x:.3f}, {y:.3f}, {z:.3f}] mm")
    return 0
