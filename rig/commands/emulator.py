"""``wristmark emulator --pty``: serve the actuator-box emulator (simulated true arm) on a pty.

Prints the device path as the first line of stdout, then serves until SIGINT / SIGTERM.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path
from types import FrameType

import numpy as np

from models.errors import InputError
from models.robot_params import HOME_PSI, RobotParams
from rig.commands.option_types import MAX_TIMEOUT_S, PSI_ABS_MAX, float_in, positive_float
from sim.actuator_emulator import ActuatorEmulator
from sim.plant import TruePlant
from sim.plant_params import PlantParams

DEFAULT_PLANT = Path(__file__).resolve().parents[2] / "configs" / "plant.yaml"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--pty", action="store_true", help="serve on a new pseudo-terminal (the only transport)")
    p.add_argument("--plant", help="plant file of the simulated true arm (default configs/plant.yaml)")
    p.add_argument("--robot", help="robot YAML (default: the reference robot)")
    p.add_argument("--watchdog", type=positive_float(MAX_TIMEOUT_S), default=0.25, metavar="S",
                   help="watchdog timeout [s] (default 0.25, as protocol v1 specifies)")
    p.add_argument("--psi0", nargs=6, type=float_in(-PSI_ABS_MAX, PSI_ABS_MAX), metavar="X",
                   help="initial configuration (default: home)")


def run(args: argparse.Namespace) -> int:
    if not args.pty:
        raise InputError("only the pseudo-terminal transport exists: pass --pty")
    if not args.watchdog > 0:
        raise InputError(f"--watchdog must be > 0 s, got {args.watchdog}")
    params = RobotParams.load(args.robot) if args.robot else RobotParams()
    plant_path = Path(args.plant) if args.plant else DEFAULT_PLANT
    plant = PlantParams.load(plant_path) if plant_path.exists() or args.plant else PlantParams()
    psi0 = np.array(args.psi0 if args.psi0 else HOME_PSI, dtype=float)
    arm = TruePlant(params, plant, psi0=psi0)
    emulator = ActuatorEmulator(arm, params, watchdog_s=args.watchdog)

    def _stop(signum: int, frame: FrameType | None) -> None:
        emulator.stop()

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    path = emulator.serve_pty()
    print(path, flush=True)
    print(f"actuator emulator (protocol v1, watchdog {args.watchdog * 1000:.0f} ms) on {path}; "
          "Ctrl-C to stop", file=sys.stderr, flush=True)
    emulator.serve_forever()
    emulator.stop()
    return 0
