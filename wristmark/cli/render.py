"""``wristmark render``: write a synthetic stereo dataset (docs/design.md "Stereo dataset format")."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cli.common_options import add_config_option, add_force_argument, add_json_flag, set_example
from wristmark.cli.option_types import (
    MAX_BLUR_PX,
    MAX_IMAGE_SCALE,
    MAX_PAIRS,
    MIN_IMAGE_SCALE,
    PSI_ABS_MAX,
    float_in,
    int_in,
    nonnegative_float,
    seed_int,
)
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs

Array = NDArray[np.float64]
# Half-widths of the random psi draw around HOME_PSI: phi [rad], d [m], theta1, delta1, theta2, delta2 [rad].
PSI_SPREAD = (0.25, 0.012, 0.2, 0.6, 0.3, 0.6)
MAX_TRIES = 400  # random draws per pair before giving up


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: the dataset to write (created; must be empty unless --force)")
    p.add_argument("--pairs", type=int_in(1, MAX_PAIRS), default=None, help="number of random pairs (default 10)")
    p.add_argument("--seed", type=seed_int(), default=0, help="random seed (configurations, background, noise)")
    add_config_option(p, "--calib")
    add_config_option(p, "--marker")
    add_config_option(p, "--robot")
    p.add_argument(
        "--psi",
        nargs="+",
        type=float_in(-PSI_ABS_MAX, PSI_ABS_MAX),
        action="append",
        metavar="Q",
        help="render this configuration: the arm's n values of psi in its order (the reference arm: phi d "
             "theta1 delta1 theta2 delta2 [rad, m, rad, rad, rad, rad]; a format-2 --robot: its names); repeatable",
    )
    p.add_argument("--scene", metavar="SCENE.yaml",
                   help="every arm of a scene file in each pair (docs/formats.md; e.g. configs/scenes/two_arms.yaml), "
                        "random configurations; truth.json per pair and arm")
    p.add_argument("--psi-file", help="text file with one configuration (the arm's n numbers) per line")
    p.add_argument("--noise", choices=("none", "default", "strong"), default="default", help="noise preset")
    p.add_argument("--settings", help="render settings YAML (overrides --noise)")
    p.add_argument("--jpeg", type=int_in(1, 100), default=None, metavar="Q",
                   help="JPEG round trip at quality Q (1-100)")
    p.add_argument("--motion-blur", type=nonnegative_float(MAX_BLUR_PX), default=None, metavar="PX",
                   help="linear motion blur length [px]")
    p.add_argument("--sleeve-specular", type=float_in(0.0, 1.0), default=None, metavar="F0",
                   help="glossy sleeve: the laminate's Fresnel F0 (0: matte, the default; 0.04: plastic): a "
                        "highlight stripe from the lights beside the lenses, clipped by the sensor")
    p.add_argument("--sleeve-roughness", type=float_in(0.01, 1.0), default=None, metavar="ALPHA",
                   help="glossy sleeve: the laminate's GGX roughness (default 0.1; 0.03 mirror-like .. 0.3 satin)")
    p.add_argument("--light-offset", type=float_in(0.0, 0.01), default=None, metavar="M",
                   help="glossy sleeve: light outputs this far [m] above and below each lens (default 0)")
    p.add_argument("--engine", choices=("fast", "pbr"), default="fast",
                   help="fast: the numba ray caster (default); pbr: path-traced with Mitsuba 3 (the optional extra "
                        "'pbr', scripts/ensure-pbr.sh; slow: about 10 s a half-size pair at 8 spp)")
    p.add_argument("--spp", type=int_in(1, 4096), default=None, help="--engine pbr: samples per pixel (default 24)")
    p.add_argument("--aperture-radius", type=float_in(0.0, 0.005), default=None, metavar="M",
                   help="--engine pbr: thin-lens aperture radius [m] (default 0: pinhole, no defocus)")
    p.add_argument("--focus-distance", type=float_in(0.01, 1.0), default=None, metavar="M",
                   help="--engine pbr: focus distance of the thin lens [m] (default 0.08)")
    p.add_argument("--image-scale", "--scale", dest="scale", type=float_in(MIN_IMAGE_SCALE, MAX_IMAGE_SCALE),
                   default=1.0, metavar="F", help="render at F x the calibrated size (default 1; --scale: old name)")
    add_json_flag(p, "a summary")
    set_example(p, "wristmark render --out runs/tour/demo --pairs 5 --seed 1",
                "wristmark render --scene configs/scenes/two_arms.yaml --out runs/tour/two --pairs 3")
    add_force_argument(p)


def psi_spread(params: object) -> tuple[float, ...]:
    """PSI_SPREAD for the reference arm; any other arm: per entry of its psi the reference's
    half-width of the same kind (revolute 0.25 rad, prismatic 0.012 m, theta 0.2 rad, delta 0.6 rad)."""
    from wristmark.models.arm_spec import ArmSpec

    if not isinstance(params, ArmSpec):
        return PSI_SPREAD
    out = [0.25 if j.joint == "revolute_z" else 0.012 for j in params.stem]
    for s in params.segments:
        out += [0.2] if s.planar is not None else [0.2, 0.6]
    return tuple(out)


def read_psi_file(path: str | Path, names: tuple[str, ...] = ("phi", "d", "theta1", "delta1", "theta2", "delta2"),
                  ) -> list[Array]:
    """Configurations from a text file: one number per entry of psi (``names``, in order) per line
    (spaces or commas), '#' comments."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: psi file not found")
    rows: list[Array] = []
    for k, line in enumerate(p.read_text().splitlines(), 1):
        line = line.split("#", 1)[0].replace(",", " ").strip()
        if not line:
            continue
        try:
            vals = [float(x) for x in line.split()]
        except ValueError as e:
            raise InputError(f"{p}:{k}: expected {len(names)} numbers, got '{line}'") from e
        if len(vals) != len(names) or not all(math.isfinite(v) for v in vals):
            raise InputError(f"{p}:{k}: expected {len(names)} finite numbers ({' '.join(names)})")
        rows.append(np.array(vals))
    if not rows:
        raise InputError(f"{p}: no configurations in the file")
    return rows


def _pbr_renderer(args: argparse.Namespace, camera: Any, marker: Any, settings: Any) -> Any:
    """The path tracer (sim.render.pbr) with the render settings' sleeve and lights and the pbr options."""
    from wristmark.sim.render.pbr import PbrSettings, PbrStereoRenderer

    given = {"spp": args.spp, "aperture_radius": args.aperture_radius, "focus_distance": args.focus_distance}
    pbr = PbrSettings(sleeve_specular=settings.sleeve_specular, sleeve_roughness=settings.sleeve_roughness,
                      light_offset=settings.light_offset, **{k: v for k, v in given.items() if v is not None})
    return PbrStereoRenderer(camera, marker, settings, pbr, seed=args.seed)


def run_scene(args: argparse.Namespace, settings: Any) -> int:
    """``render --scene``: every arm of a scene in each pair, at random configurations (each tip in
    a box 1.5 times the scene's cube around its workspace centre); writes calib.yaml (the scene
    camera), one marker file per arm (marker_NAME.yaml), the images and truth.json (per pair, per
    arm: docs/formats.md "Scene dataset")."""
    from wristmark.cvs.calibration.load import save_calibration
    from wristmark.cvs.camera import scaled_stereo_camera
    from wristmark.cvs.marker.family import marker_file_text
    from wristmark.models.arm_shape import arm_shape, transformed
    from wristmark.sim.dataset import scene_truth_entry, write_pair_images
    from wristmark.sim.render.stereo_renderer import StereoRenderer
    from wristmark.sim.scene_poses import random_tip_psi
    from wristmark.sim.scene_setup import load_scene_setup

    refused = [f"--{k.replace('_', '-')}" for k in ("robot", "marker", "calib", "psi", "psi_file")
               if getattr(args, k, None)]
    if refused or args.engine != "fast":
        raise InputError(f"{', '.join(refused) or '--engine pbr'}: not with --scene (the scene file names each "
                         "arm's files; configurations are drawn at random)")
    setup = load_scene_setup(args.scene)
    camera = setup.camera if args.scale == 1.0 else scaled_stereo_camera(setup.camera, args.scale)
    rng = np.random.default_rng(args.seed)
    n_pairs = args.pairs or 10
    configs = [{n: random_tip_psi(s.params, setup.scene.cube_size, rng) for n, s in setup.arms.items()}
               for _ in range(n_pairs)]
    claim_outputs(dirs=[args.out], force=args.force)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_calibration(out / "calib.yaml", camera)
    for n, s in setup.arms.items():
        (out / f"marker_{n}.yaml").write_text(marker_file_text(s.marker))
    renderer = StereoRenderer(camera, setup.markers, settings, seed=args.seed)
    entries = []
    for k, q in enumerate(configs):
        shapes = [transformed(arm_shape(setup.arms[n].params, q[n]), setup.base(n)) for n in setup.names]
        scene = renderer.render_arms(shapes)
        write_pair_images(out, k, scene.left, scene.right)
        entries.append(scene_truth_entry(k, scene, setup.names) | {"psi": {n: q[n].tolist() for n in setup.names}})
    (out / "truth.json").write_text(json.dumps(entries, indent=1))
    print(f"wrote {n_pairs} stereo pairs of {len(setup.names)} arms ({', '.join(setup.names)}) to {args.out}")
    return 0


def run(args: argparse.Namespace) -> int:
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.camera import scaled_stereo_camera
    from wristmark.cvs.tracking.warmup import warm_up
    from wristmark.models.arm_shape import arm_shape
    from wristmark.models.arm_spec import ArmSpec, arm_names, load_loop_arm
    from wristmark.models.limits import check_limits
    from wristmark.models.marker import MarkerModel
    from wristmark.sim.dataset import DatasetWriter
    from wristmark.sim.render.settings import RenderSettings, noise_preset
    from wristmark.sim.render.stereo_renderer import StereoRenderer
    from wristmark.sim.visibility import marker_visible, random_visible_psi

    if args.pairs is not None and args.pairs < 1:
        raise InputError(f"--pairs must be >= 1, got {args.pairs}")
    if not args.scale > 0 or args.scale > 4:
        raise InputError(f"--scale must be in (0, 4], got {args.scale}")
    overrides: dict[str, object] = {}
    if args.jpeg is not None:
        if not 1 <= args.jpeg <= 100:
            raise InputError(f"--jpeg must be a quality in 1..100, got {args.jpeg}")
        overrides["jpeg_quality"] = args.jpeg
    if args.motion_blur is not None:
        if not args.motion_blur >= 0:
            raise InputError(f"--motion-blur must be >= 0 px, got {args.motion_blur}")
        overrides["motion_blur"] = args.motion_blur
    for key in ("sleeve_specular", "sleeve_roughness", "light_offset"):  # the glossy sleeve (RenderSettings)
        if getattr(args, key, None) is not None:
            overrides[key] = getattr(args, key)
    if args.settings:
        from dataclasses import replace

        settings = replace(RenderSettings.load(args.settings), **overrides)  # type: ignore[arg-type]
        settings.validate()
    else:
        settings = noise_preset(args.noise, **overrides)

    if args.scene is not None:
        return run_scene(args, settings)
    calib = args.calib or str(default_config("camera.yaml"))
    camera = load_calibration(calib)
    if args.scale != 1.0:
        camera = scaled_stereo_camera(camera, args.scale)
    marker = MarkerModel.load(args.marker) if args.marker else MarkerModel()
    params = load_loop_arm(args.robot, marker)
    if isinstance(params, ArmSpec) and not args.calib:  # the default endoscope framed on this arm
        from wristmark.sim.setup import camera_for_arm

        camera = camera_for_arm(camera, params, marker)

    names = arm_names(params)
    for q in args.psi or []:
        if len(q) != len(names):
            raise InputError(f"argument --psi: expected {len(names)} values ({' '.join(names)}) for "
                             f"{args.robot or 'the reference arm'}, got {len(q)}")
    given: list[Array] = [np.asarray(q, float) for q in (args.psi or [])]
    if args.psi_file:
        given += read_psi_file(args.psi_file, names)
    rng = np.random.default_rng(args.seed)
    if given:
        if args.pairs is not None and args.pairs != len(given):
            raise InputError(f"--pairs {args.pairs} disagrees with the {len(given)} given configurations")
        configs = [check_limits(params, q) for q in given]
        for q in configs:
            if not marker_visible(camera, marker, arm_shape(params, q)):
                raise InputError(f"the marker is not seen by both cameras at psi = {np.round(q, 4).tolist()}")
    else:
        configs = [
            random_visible_psi(params, camera, marker, rng, psi_spread(params), MAX_TRIES)
            for _ in range(args.pairs or 10)
        ]

    claim_outputs(dirs=[args.out], force=args.force)
    warm_up(jit=False)  # OpenCV's threads (cvs.tracking.warmup); the renderer's kernels load on its first frame
    renderer: Any = (_pbr_renderer(args, camera, marker, settings) if args.engine == "pbr"
                     else StereoRenderer(camera, marker, settings, seed=args.seed))
    writer = DatasetWriter(args.out, camera, marker)
    for q in configs:
        writer.add(renderer.render(arm_shape(params, q)))
    if args.json:
        print(json.dumps({"out": str(args.out), "pairs": len(configs), "psi": [q.tolist() for q in configs]}))
    else:
        print(f"wrote {len(configs)} stereo pairs to {args.out}")
    return 0
