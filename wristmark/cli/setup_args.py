"""Command-line options shared by the commands that run a servo loop (experiment, servo): which
configuration files, and overrides of the loop (cycle, latency, sensor, image scale, seed) and
of the controller kind. ``setup_from_args`` loads and validates them into a SimSetup (the
simulated bench) or, for the hardware path, a :class:`rig.loop.loop_setup.LoopSetup` without
importing the simulated bench. The stereo calibration is ``--calib`` (``--camera`` names a
frame source in ``servo``)."""

from __future__ import annotations

import argparse
import dataclasses
from typing import TYPE_CHECKING, Any

from wristmark.cli.common_options import add_config_option
from wristmark.cli.option_types import (
    MAX_CONTROL_DT,
    MAX_IMAGE_SCALE,
    MIN_CONTROL_DT,
    MIN_IMAGE_SCALE,
    float_in,
    nonnegative_float,
    seed_int,
)
from wristmark.models.errors import ConfigError, InputError

if TYPE_CHECKING:
    from wristmark.rig.loop.loop_setup import LoopSetup

SIM_ONLY = ("plant", "latency", "sensor")  # options that only the simulated bench has
MAX_OPEN_ON_LOST_S = 5.0  # [s] the longest open-loop walk without the marker --open-loop-on-lost takes


def add_setup_arguments(p: argparse.ArgumentParser) -> None:
    """Configuration files and loop/controller overrides."""
    add_config_option(p, "--plant")
    p.add_argument("--controller", metavar="NAME", help="controller kind (paper, qp, ...)")
    p.add_argument("--controller-config", metavar="YAML", help="controller file (default configs/controller.yaml)")
    p.add_argument("--rig", metavar="YAML", help="rig/loop file (default configs/rig.yaml)")
    add_config_option(p, "--robot")
    add_config_option(p, "--calib")
    add_config_option(p, "--marker")
    p.add_argument("--dt", type=float_in(MIN_CONTROL_DT, MAX_CONTROL_DT), metavar="S",
                   help="control cycle [s] (paper: 0.060)")
    p.add_argument("--latency", type=nonnegative_float(MAX_CONTROL_DT), metavar="S",
                   help="simulated bench: capture -> command latency [s]")
    p.add_argument("--sensor", choices=("vision", "truth-noise"),
                   help="simulated bench: rendered images + tracker (default) or truth+noise (fast)")
    p.add_argument("--image-scale", type=float_in(MIN_IMAGE_SCALE, MAX_IMAGE_SCALE), metavar="F",
                   help="images at F x the calibrated size (simulated bench: rendered so; a camera: delivers so)")
    p.add_argument("--seed", type=seed_int(), help="random seed (noise, rendering, tracker)")


def add_model_arguments(p: argparse.ArgumentParser, per_arm: bool = False) -> None:
    """``--model MODEL.yaml`` (the identified arm the loop commands) and ``--open-loop-on-lost S``;
    ``per_arm``: repeatable, ``NAME=MODEL.yaml`` per arm of a scene (``servo --scene``)."""
    if per_arm:
        p.add_argument("--model", metavar="MODEL.yaml", action="append",
                       help="identified arm (wristmark identify): the loop commands its inverse, plays and lag "
                            "(docs/identification.md); with --scene NAME=MODEL.yaml, repeatable (one per arm)")
    else:
        p.add_argument("--model", metavar="MODEL.yaml",
                       help="identified arm (wristmark identify): the loop commands its inverse, plays and lag "
                            "(docs/identification.md)")
    p.add_argument("--open-loop-on-lost", type=nonnegative_float(MAX_OPEN_ON_LOST_S), metavar="S",
                   help="with --model: while the marker is lost, walk on along the target open loop for S seconds, "
                        "then hold (default 0: hold at once; rig open_loop_on_lost)")


def add_registration_argument(p: argparse.ArgumentParser) -> None:
    """``--registration FILE``: the host's world_T_left from a registration file (wristmark register)."""
    add_config_option(p, "--registration")


def setup_from_args(args: argparse.Namespace, simulated: bool = True, **rig_overrides: Any) -> Any:
    """Load the configuration files and apply the command-line overrides (plus ``rig_overrides``
    that are not None), validated; an unknown controller kind lists the valid ones.

    simulated: a SimSetup (the simulated bench, with its plant file); False: a LoopSetup for the
    hardware path (the simulated bench is not imported; its options are refused)."""

    if getattr(args, "open_loop_on_lost", None) and not getattr(args, "model", None):
        raise ConfigError("--open-loop-on-lost needs --model (an identified arm to trust without the marker)")
    if getattr(args, "open_loop_on_lost", None) is not None:
        rig_overrides = {**rig_overrides, "open_loop_on_lost": args.open_loop_on_lost}
    setup: LoopSetup
    if simulated:
        from wristmark.sim.setup import load_setup

        setup = load_setup(robot=args.robot, marker=args.marker, camera=args.calib, plant=args.plant,
                           rig=args.rig, controller=args.controller_config)
    else:
        from wristmark.rig.loop.loop_setup import load_loop_setup

        given = [f"--{k}" for k in SIM_ONLY if getattr(args, k, None) is not None]
        if given:
            raise InputError(f"{', '.join(given)}: only for the simulated bench, not with a camera")
        setup = load_loop_setup(robot=args.robot, marker=args.marker, camera=args.calib, rig=args.rig,
                                controller=args.controller_config)
    if getattr(args, "model", None):  # --model (experiment, servo): docs/identification.md
        from wristmark.models.model_file import load_model

        setup = setup.with_changes(model=load_model(one_model(args.model)))
    if getattr(args, "registration", None):
        from wristmark.cvs.calibration.registration_file import load_registration

        setup = setup.with_changes(registration=load_registration(args.registration).world_T_left)
    return apply_overrides(setup, args, **rig_overrides)


def one_model(model: str | list[str]) -> str:
    """The one arm's ``--model`` (servo's is repeatable, for the arms of a scene: once without)."""
    if isinstance(model, str):
        return model
    if len(model) > 1:
        raise InputError(f"--model given {len(model)} times: one identified model per arm needs --scene "
                         "(--model NAME=MODEL.yaml for each)")
    return model[0]


SCENE_FILES = ("robot", "marker", "plant", "calib", "model", "registration", "open_loop_on_lost")


def scene_setup_from_args(args: argparse.Namespace) -> Any:
    """``--scene FILE``: the scene's setup (sim.scene_setup) with the command line's loop and
    controller overrides applied to every arm. The arms' own files come from the scene file:
    ``--robot``, ``--marker``, ``--plant``, ``--calib``, ``--model``, ``--registration`` are refused."""
    from wristmark.sim.scene_setup import load_scene_setup

    given = [f"--{k.replace('_', '-')}" for k in SCENE_FILES if getattr(args, k, None) is not None]
    if given:
        raise InputError(f"{', '.join(given)}: not with --scene (each arm's files are named in the scene file)")
    scene = load_scene_setup(args.scene, rig=args.rig, controller=args.controller_config)
    for name in scene.names:
        scene.arms[name] = apply_overrides(scene.arms[name], args)
    return scene


def apply_overrides(setup: Any, args: argparse.Namespace, **rig_overrides: Any) -> Any:
    """The command line's loop and controller overrides (``--dt``, ``--latency``, ``--sensor``,
    ``--image-scale``, ``--seed``, ``--controller``, plus ``rig_overrides``) applied to ``setup``,
    validated."""
    from wristmark.solvers.controller_registry import make_controller

    changes: dict[str, Any] = {}
    if args.dt is not None:
        changes["control_dt"] = args.dt
        if args.latency is None and setup.rig.vision_latency >= args.dt:
            changes["vision_latency"] = 0.75 * args.dt
        if setup.rig.frame_wait >= args.dt:
            changes["frame_wait"] = 0.5 * args.dt
        if setup.rig.command_phase >= args.dt:
            changes["command_phase"] = 0.75 * args.dt
    if args.latency is not None:
        changes["vision_latency"] = args.latency
    for key, value in (("sensor", args.sensor), ("image_scale", args.image_scale), ("seed", args.seed),
                       *rig_overrides.items()):
        if value is not None:
            changes[key] = value
    if changes:
        rig = dataclasses.replace(setup.rig, **changes)
        try:
            rig.validate()
        except ConfigError as e:
            raise ConfigError(f"command-line options: {e}") from None
        setup = setup.with_changes(rig=rig)
    ctrl = setup.controller
    if args.controller:
        ctrl = dataclasses.replace(ctrl, kind=args.controller)
    if args.dt is not None:
        ctrl = dataclasses.replace(ctrl, dt=args.dt)
    make_controller(setup.params, ctrl)  # validates the kind (lists the valid ones)
    return setup.with_changes(controller=ctrl)
