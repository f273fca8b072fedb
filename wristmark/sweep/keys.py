"""The keys a sweep SPEC may name (docs/design.md "Sweeps"): ``wristmark experiment`` options and
dotted configuration keys.

An option key is the name of a ``wristmark experiment`` option (``latency``, ``dt``, ``sensor``,
``controller``, ``duration``, ``image_scale`` or ``image-scale``, ``plant`` (a file), ...); its
value becomes command-line text, so it is checked by the very parser of that command.
A dotted key ``NS.field[.index ...]`` changes one value of a configuration file: ``NS`` is one
of plant, rig, controller, robot, marker, camera; list indices are integers
(``plant.backlash.0``; a format-2 robot file's ``robot.segments.0.length``). The trial writes the
changed file and passes it to the experiment (``--plant``, ``--rig``, ``--controller-config``,
...), so a trial is a plain ``wristmark experiment`` run whose command line says everything (a
changed format-2 robot file keeps the plant shipped beside the original, ``--plant``). A rig or controller key may name
its section of the file (``rig.loop.gate`` = ``rig.gate``, ``controller.qp.ki`` = ``controller.ki``).
"""

from __future__ import annotations

import argparse
import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from wristmark.models.config_io import save_yaml, to_mapping
from wristmark.models.errors import ConfigError


class SpecError(ConfigError):
    """A sweep SPEC is malformed (one line naming the key and the fix)."""


# Options a sweep sets itself, or that make no sense in a trial.
RESERVED_OPTIONS = {"help": "", "json": "", "out": "", "no_progress": "", "view": "", "force": "",
                    "seed": " (list the seeds under 'seeds:')"}


def _load_plant(path: Path) -> dict[str, Any]:
    from wristmark.sim.plant_params import PlantParams

    return to_mapping(PlantParams.load(path))


def _load_rig(path: Path) -> dict[str, Any]:
    from wristmark.rig.loop.rig_config import RigConfig

    return to_mapping(RigConfig.load(path))


def _load_controller(path: Path) -> dict[str, Any]:
    from wristmark.solvers.controller import ControllerConfig

    return to_mapping(ControllerConfig.load(path))


def _load_robot(path: Path) -> dict[str, Any]:
    """The robot file as its complete mapping: the flat reference-arm file's RobotParams, or a
    format-2 file's ArmSpec (keys such as ``robot.segments.0.length`` [m] or
    ``robot.stem.0.range.1``; without ``tip_offset``, which belongs to the marker file)."""
    from wristmark.models.arm_spec import load_arm, robot_file_format
    from wristmark.models.robot_params import RobotParams

    if robot_file_format(path) == 2:
        return {k: v for k, v in to_mapping(load_arm(path)).items() if k != "tip_offset"}
    return to_mapping(RobotParams.load(path))


def _load_marker(path: Path) -> dict[str, Any]:
    from wristmark.models.marker import MarkerModel

    return to_mapping(MarkerModel.load(path))


def _load_camera(path: Path) -> dict[str, Any]:
    from wristmark.cvs.calibration.load import calibration_mapping, load_calibration

    return calibration_mapping(load_calibration(path))


@dataclass(frozen=True)
class Namespace:
    """A configuration file a dotted key can change: its experiment option, default, loader."""

    option: str  # the option's dest in ``wristmark experiment`` (e.g. "controller_config")
    flag: str  # its command-line flag (e.g. "--controller-config")
    default: str  # file name in configs/
    load: Callable[[Path], dict[str, Any]]  # the file as its complete, validated mapping


NAMESPACES: dict[str, Namespace] = {
    "plant": Namespace("plant", "--plant", "plant.yaml", _load_plant),
    "rig": Namespace("rig", "--rig", "rig.yaml", _load_rig),
    "controller": Namespace("controller_config", "--controller-config", "controller.yaml", _load_controller),
    "robot": Namespace("robot", "--robot", "robot.yaml", _load_robot),
    "marker": Namespace("marker", "--marker", "marker.yaml", _load_marker),
    "camera": Namespace("camera", "--camera", "camera.yaml", _load_camera),
}
FILE_OPTIONS = frozenset(ns.option for ns in NAMESPACES.values()) | {"registration"}


def check_value(key: str, value: Any) -> None:
    """Raise SpecError for None, NaN or an infinity anywhere in ``value``."""
    if value is None:
        raise SpecError(f"'{key}': a value is missing (null)")
    if isinstance(value, float) and not math.isfinite(value):
        raise SpecError(f"'{key}': {value} is not a finite number")
    if isinstance(value, list | tuple):
        for v in value:
            check_value(key, v)
    elif isinstance(value, dict):
        for k, v in value.items():
            check_value(f"{key}.{k}", v)


def format_value(value: Any) -> str:
    """A value as one CSV cell / command-line word (floats exactly: repr round-trips)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)


class _RaisingParser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise SpecError(message)


class ExperimentOptions:
    """The options of ``wristmark experiment``, read from its own parser."""

    def __init__(self) -> None:
        from wristmark.cli import experiment

        self.parser = _RaisingParser(prog="wristmark experiment", add_help=False)
        experiment.add_arguments(self.parser)
        self.by_name: dict[str, argparse.Action] = {}
        for action in self.parser._actions:
            for flag in action.option_strings:
                if flag.startswith("--"):
                    self.by_name[flag[2:].replace("-", "_")] = action
        name = next(a for a in self.parser._actions if not a.option_strings and a.dest == "name")
        self.experiments = tuple(name.choices or ())

    def valid_names(self) -> list[str]:
        """Option names a SPEC may use (dests, underscores)."""
        return sorted({a.dest for a in self.by_name.values() if a.dest not in RESERVED_OPTIONS})

    def action(self, key: str) -> argparse.Action:
        """The option named ``key`` (``image_scale`` or ``image-scale``); SpecError if unknown."""
        action = self.by_name.get(key.replace("-", "_"))
        if action is None:
            raise SpecError(f"unknown key '{key}': not an option of wristmark experiment nor a dotted key "
                            f"{'/'.join(NAMESPACES)}.NAME (options: {', '.join(self.valid_names())})")
        if action.dest in RESERVED_OPTIONS:
            raise SpecError(f"'{key}' cannot be set in a sweep{RESERVED_OPTIONS[action.dest]}")
        return action

    def tokens(self, key: str, value: Any) -> list[str]:
        """Command-line words of option ``key`` = ``value`` (type-checked by the parser later)."""
        action = self.action(key)
        flag = next(f for f in action.option_strings if f.startswith("--"))
        check_value(key, value)
        if isinstance(value, dict):
            raise SpecError(f"'{key}': expected a value, got a mapping")
        if action.nargs == 0:  # a flag such as store_true
            if not isinstance(value, bool):
                raise SpecError(f"'{key}' is a flag: its value must be true or false, got {value!r}")
            return [flag] if value else []
        if isinstance(value, bool):
            raise SpecError(f"'{key}' takes a value, not {str(value).lower()}")
        if action.nargs in ("+", "*") or isinstance(action.nargs, int):
            values = value if isinstance(value, list | tuple) else [value]
            return [flag, *(format_value(v) for v in values)]
        if isinstance(value, list | tuple):
            raise SpecError(f"'{key}' takes one value, got the list {format_value(value)}")
        return [flag, format_value(value)]

    def parse(self, argv: list[str]) -> argparse.Namespace:
        """Parse ``[NAME, options...]`` as ``wristmark experiment`` does; SpecError on a bad one."""
        return self.parser.parse_args(argv)


def split_dotted(key: str) -> tuple[str, list[str]] | None:
    """(namespace, path parts) of a dotted key, None for an option name."""
    if "." not in key:
        return None
    ns, *parts = key.split(".")
    if ns not in NAMESPACES:
        raise SpecError(f"unknown key '{key}': a dotted key starts with one of {', '.join(NAMESPACES)}")
    if not all(parts):
        raise SpecError(f"'{key}': empty part in a dotted key")
    layout = _layout(ns)
    if len(parts) > 1 and parts[0] in set(layout.values()):  # a section of the file: rig.loop.gate = rig.gate
        where = layout.get(parts[1])
        if where is not None and where != parts[0]:
            raise SpecError(f"unknown key '{key}': '{parts[1]}' is in {ns}.yaml's '{where}:' section "
                            f"({ns}.{where}.{parts[1]}, or {ns}.{parts[1]})")
        parts = parts[1:]
    return ns, parts


def _layout(ns: str) -> dict[str, str]:
    """Each key of namespace ``ns`` -> its section in the shipped file (rig.yaml's loop/bench,
    controller.yaml's paper/qp/backlash/probe); empty for a file without sections."""
    if ns == "rig":
        from wristmark.rig.loop.rig_config import RIG_LAYOUT

        return RIG_LAYOUT
    if ns == "controller":
        from wristmark.solvers.controller import CONTROLLER_LAYOUT

        return CONTROLLER_LAYOUT
    return {}


def set_dotted(mapping: dict[str, Any], key: str, parts: list[str], value: Any) -> dict[str, Any]:
    """Copy of ``mapping`` with the value at ``parts`` replaced; SpecError for a path that does
    not exist there (listing what does)."""
    out = copy.deepcopy(mapping)
    node: Any = out
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join([key.split(".")[0], *parts[:depth]])
        if isinstance(node, dict):
            if part not in node:
                raise SpecError(f"unknown key '{key}': '{where}' has no '{part}' "
                                f"(valid: {', '.join(sorted(node))})")
            if last:
                node[part] = copy.deepcopy(value)
            node = node[part]
        elif isinstance(node, list):
            if not (part.isdigit() and int(part) < len(node)):
                raise SpecError(f"unknown key '{key}': '{where}' is a list of {len(node)}, "
                                f"'{part}' is not an index 0..{len(node) - 1}")
            if last:
                node[int(part)] = copy.deepcopy(value)
            node = node[int(part)]
        else:
            raise SpecError(f"unknown key '{key}': '{where}' is a single value, it has no '{part}'")
    return out


def write_configs(configs: dict[str, dict[str, Any]], folder: Path) -> list[str]:
    """Write each changed configuration to ``folder/NS.yaml``; the command-line words that pass
    them to ``wristmark experiment``."""
    folder.mkdir(parents=True, exist_ok=True)
    words: list[str] = []
    for ns, mapping in sorted(configs.items()):
        path = folder / f"{ns}.yaml"
        save_yaml(path, mapping)
        words += [NAMESPACES[ns].flag, str(path)]
    return words
