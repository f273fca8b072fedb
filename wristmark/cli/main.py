"""The ``wristmark`` command line: a thin dispatcher over ``cli/<name>.py`` (and the sweep's
command, ``sweep/command.py``: the sweep drives this command line, so it stands above it).

Each command module defines ``add_arguments(parser)`` and ``run(args) -> int``; it is imported
only when its command runs, so ``wristmark fk`` does not pay for OpenCV or Meshcat. Errors that
wristmark raises on purpose (``WristmarkError``) print one line to stderr and exit 2; set
``WRISTMARK_DEBUG=1`` to see tracebacks of unexpected errors.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import NoReturn

from wristmark.models.errors import WristmarkError

COMMANDS: dict[str, str] = {
    "fk": "forward kinematics and the 6x6 tip Jacobian of a configuration",
    "urdf": "write the pseudo-rigid URDF of the arm",
    "render": "render a synthetic stereo dataset of the marked arm",
    "track": "track the wrist marker in stereo image pairs",
    "servo": "run the closed loop (simulated rig, or --serial PORT for hardware)",
    "experiment": "run the paper's experiments: cube, accuracy, load",
    "sweep": "run many seeded experiments over a grid or random samples (dask.distributed)",
    "emulator": "serve the actuator-box emulator on a pseudo-terminal",
    "view": "serve or snapshot the Meshcat 3D view (live, replay or home pose)",
    "marker": "print a marker file's sleeve at 1:1 (SVG or PDF) to wrap around the arm",
    "calib": "convert a calibration (YAML, OpenCV, ROS pair, Kalibr) to the project's YAML, or summarise it",
    "calibrate": "stereo calibration from chessboard or ChArUco image pairs or a video source",
    "register": "find world_T_left (the camera's pose in {w}) by moving the arm and tracking the marker",
    "identify": "fit how the real arm differs from its robot file from tracked motion (the --model of experiment)",
}


# The module of each command: ``wristmark.cli.<name>`` unless named here.
COMMAND_MODULES: dict[str, str] = {"sweep": "wristmark.sweep.command"}


def command_module(name: str) -> str:
    """The dotted module that defines ``add_arguments`` and ``run`` of command ``name``."""
    return COMMAND_MODULES.get(name, f"wristmark.cli.{name}")


EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE: what a shell reports for a writer whose reader closed the pipe


def _discard_stdout() -> None:
    """Point stdout at /dev/null so that flushing it at exit raises nothing more."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


class OneLineParser(argparse.ArgumentParser):
    """argparse with usage errors reported as one line on stderr (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Top-level parser; adds the arguments of ``command`` only (lazy imports)."""
    parser = OneLineParser(
        prog="wristmark",
        description="Stereo tracking of a continuum manipulator's wrist marker and closed-loop control.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == command:
            module = importlib.import_module(command_module(name))
            module.add_arguments(p)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    command = next((a for a in args_list if not a.startswith("-")), None)
    if command not in COMMANDS:
        command = None
    try:
        parser = build_parser(command)
        args = parser.parse_args(args_list)
        if args.command is None:
            parser.print_help()
            return 2
        module = importlib.import_module(command_module(args.command))
        status = int(module.run(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return status
    except BrokenPipeError:  # the reader went away (``wristmark fk --json | head -c 10``): end quietly
        _discard_stdout()
        return EXIT_BROKEN_PIPE
    except WristmarkError as e:
        print(f"wristmark {command or ''}: error: {e}".replace("  ", " "), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("wristmark: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - last resort: one line, no traceback
        if os.environ.get("WRISTMARK_DEBUG"):
            raise
        print(f"wristmark {command or ''}: internal error: {type(e).__name__}: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
