"""The options that mean the same in every command, defined once: ``--calib``, ``--marker``,
``--robot``, ``--plant``, ``--registration`` (the same metavar and help everywhere, each command
adding only its default or a note), ``--json`` (a flag: the result as JSON on stdout; or, in
``servo`` and ``experiment``, ``--json FILE.json``: the result as JSON in that file), ``--out``
(an output folder, metavar DIR, or an output file, metavar FILE.ext), ``--force`` (overwrite
outputs), ``--host`` (who may watch the 3D view), and the example that ends each command's
``--help``. tests/cli/test_cli_help.py checks every command against them."""

from __future__ import annotations

import argparse

from wristmark.viz.web_hosts import host_address

# option -> (metavar, help): the meaning, the same in every command
CONFIG_OPTIONS: dict[str, tuple[str, str]] = {
    "--calib": ("SPEC", "stereo calibration: the project's YAML, OpenCV .yml/.xml, a ROS pair LEFT.yaml,RIGHT.yaml "
                        "or a Kalibr camchain"),
    "--marker": ("YAML", "marker file"),
    "--robot": ("YAML", "robot file"),
    "--plant": ("YAML", "plant file of the simulated bench: how the simulated true arm differs from the model"),
    "--registration": ("REG.yaml", "registration file (wristmark register): its world_T_left replaces the "
                                   "calibration's"),
}
SHIPPED_DEFAULT = {"--calib": "configs/camera.yaml", "--marker": "configs/marker.yaml",
                   "--robot": "configs/robot.yaml", "--plant": "configs/plant.yaml"}
JSON_FLAG_HELP = "print {what} as JSON on stdout"
JSON_FILE_HELP = "write {what} as JSON to FILE.json"
FORCE_HELP = "overwrite existing outputs: an output file, or a non-empty output folder (emptied first)"
HOST_HELP = ("3D view: also listen on ADDRESS (e.g. 0.0.0.0: every interface; default: 127.0.0.1 and ::1 only, "
             "nobody else can watch)")


def add_config_option(p: argparse.ArgumentParser | argparse._ArgumentGroup, option: str, required: bool = False,
                      default: bool = True, note: str = "", repeat: bool = False) -> argparse.Action:
    """Add ``option`` (a key of CONFIG_OPTIONS) with its shared metavar and help; ``default``:
    say that the shipped file is the default; ``note``: what this command adds (after a ';');
    ``repeat``: the option may be given several times (a list)."""
    metavar, text = CONFIG_OPTIONS[option]
    if default and not required and option in SHIPPED_DEFAULT:
        text += f" (default {SHIPPED_DEFAULT[option]})"
    return p.add_argument(option, metavar=metavar, required=required, help=text + (f"; {note}" if note else ""),
                          action="append" if repeat else "store")


def add_json_flag(p: argparse.ArgumentParser, what: str = "the result") -> argparse.Action:
    """``--json``: print ``what`` as JSON on stdout."""
    return p.add_argument("--json", action="store_true", help=JSON_FLAG_HELP.format(what=what))


def add_force_argument(p: argparse.ArgumentParser) -> argparse.Action:
    """``--force``: a command that writes outputs may overwrite them."""
    return p.add_argument("--force", action="store_true", help=FORCE_HELP)


def add_host_argument(p: argparse.ArgumentParser) -> argparse.Action:
    """``--host ADDRESS``: the commands that serve the 3D view also listen on ADDRESS."""
    return p.add_argument("--host", type=host_address, metavar="ADDRESS", help=HOST_HELP)


def set_example(p: argparse.ArgumentParser, *examples: str) -> None:
    """End ``p``'s --help with the example command lines (kept as written)."""
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = "example:\n" + "\n".join(f"  {e}" for e in examples)
