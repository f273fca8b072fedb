"""``wristmark track``: tip and marker pose in each stereo pair (DESIGN.md "Command line").

Pairs are processed in order as one sequence (ROI tracking from pair to pair). With ``--json``
one object per pair and line: left, right, ok, tip, R, t (pose of {wm} in {ll}, metres),
corners_left, corners_right (raw pixels), rms_px, time_ms, and axis_source (what decided the
direction of z_wm: cvs.marker_tracker); ``"ok": false`` with a ``reason``
when the marker is not found (exit status stays 0: that is a result, not an error).
Errors are for the whole command (one line on stderr, exit 2): an odd number of paths, a
missing file (all paths are checked before any pair is tracked), and an unreadable (corrupt)
or wrong-size image — that one is found when its pair is reached, after the earlier pairs'
lines were printed.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from models.errors import InputError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--calib", required=True, help="stereo calibration (YAML of DESIGN.md or OpenCV FileStorage)")
    p.add_argument("--marker", help="marker YAML (default: the reference marker)")
    p.add_argument("--registration", metavar="FILE",
                   help="registration file (wristmark register): overrides the calibration's world_T_left; "
                   "the JSON then also has tip_world [m] in {w}")
    p.add_argument("images", nargs="+", metavar="LEFT RIGHT", help="stereo pairs: left and right image paths")
    p.add_argument(
        "--detector",
        choices=("auto", "paper", "saddle"),
        default="auto",
        help="corner detector (auto: the paper's detector when installed)",
    )
    p.add_argument(
        "--max-rms",
        type=float,
        default=None,
        metavar="PX",
        help="largest accepted reprojection RMS [px] (default 0.75)",
    )
    p.add_argument(
        "--axis-hint",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="expected direction of the marker's z axis (towards the tip) in the left camera frame; "
        "default: decided from the images (the arm's side of the sleeve), else +x (tip to the right)",
    )
    p.add_argument("--json", action="store_true", help="one JSON object per pair and line on stdout")


def read_image(path: Path) -> NDArray[np.uint8]:
    """Read an image as cv2.imread does (BGR or grayscale uint8); InputError if unreadable."""
    import cv2

    try:
        data = np.fromfile(str(path), dtype=np.uint8)
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    except (OSError, cv2.error) as e:
        raise InputError(f"{path}: cannot read the image ({e})") from e
    if img is None:
        raise InputError(f"{path}: not a readable image (corrupt or unsupported format)")
    if img.dtype != np.uint8:
        raise InputError(f"{path}: expected an 8-bit image, got {img.dtype}")
    return np.asarray(img)


def _round(a: Any, nd: int) -> Any:
    return np.round(np.asarray(a, float), nd).tolist()


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from cvs.calibration_io import load_calibration
    from cvs.marker import MarkerModel
    from cvs.marker_tracker import MarkerTracker, TrackerSettings
    from cvs.registration_io import apply_registration

    paths = [Path(p) for p in args.images]
    if len(paths) % 2:
        raise InputError(f"images come in LEFT RIGHT pairs, got {len(paths)} paths")
    for p in paths:
        if not p.is_file():
            raise InputError(f"{p}: image file not found")
    settings = TrackerSettings(detector=args.detector)
    if args.max_rms is not None:
        if not (math.isfinite(args.max_rms) and args.max_rms > 0):
            raise InputError(f"--max-rms must be > 0 px, got {args.max_rms}")
        settings = replace(settings, max_rms_px=args.max_rms, good_rms_px=min(settings.good_rms_px, args.max_rms))
    hint = None
    if args.axis_hint is not None:
        hint = np.asarray(args.axis_hint, float)
        if not (np.all(np.isfinite(hint)) and np.linalg.norm(hint) > 0):
            raise InputError(f"--axis-hint must be a finite non-zero direction, got {args.axis_hint}")
    camera = apply_registration(load_calibration(args.calib), args.registration)
    marker = MarkerModel.load(args.marker) if args.marker else MarkerModel()
    tracker = MarkerTracker(camera, marker, settings)
    for lp, rp in zip(paths[0::2], paths[1::2]):
        left, right = read_image(lp), read_image(rp)
        try:
            res = tracker.track(left, right, axis_hint_left=hint)
        except InputError as e:
            raise InputError(f"{lp} / {rp}: {e}") from e
        out: dict[str, Any] = {"left": str(lp), "right": str(rp), "ok": res.ok}
        if res.ok and res.T_left_marker is not None and res.tip_left is not None:
            out |= {
                "tip": _round(res.tip_left, 9),
                "R": _round(res.T_left_marker[:3, :3], 9),
                "t": _round(res.T_left_marker[:3, 3], 9),
            }
            if args.registration and res.tip_world is not None:
                out["tip_world"] = _round(res.tip_world, 9)
        else:
            out["reason"] = res.reason
        out |= {
            "corners_left": _round(res.corners_left, 4),
            "corners_right": _round(res.corners_right, 4),
            "rms_px": round(res.rms_px, 5) if res.ok else None,
            "time_ms": round(res.time_ms, 3),
        }
        if res.ok:
            out["axis_source"] = res.axis_source
        if args.json:
            print(json.dumps(out), flush=True)
        elif res.ok and res.tip_left is not None:
            x, y, z = (1e3 * res.tip_left).tolist()
            print(
                f"{lp.name} {rp.name}: tip in {{ll}} [{x:.3f}, {y:.3f}, {z:.3f}] mm, "
                f"rms {res.rms_px:.3f} px, {res.time_ms:.1f} ms",
                flush=True,
            )
        else:
            print(f"{lp.name} {rp.name}: no pose ({res.reason})", flush=True)
    return 0
