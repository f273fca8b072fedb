"""``wristmark calibrate``: stereo calibration from board image pairs or a frame source.

``--board chessboard:CxR:SQUARE | charuco:CxR:SQUARE:MARKER:DICT`` (docs/design.md "Calibration
files"), ``LEFT RIGHT [LEFT RIGHT ...]`` or ``--source SPEC`` (a dataset folder, video, camera
or bag: cvs.sources.open_source), ``--out C.yaml`` (refused if it exists, unless ``--force``),
``--report DIR``. Dropped views are named on stderr; ``--json`` prints the result on stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from wristmark.cli.common_options import add_force_argument, add_json_flag, set_example
from wristmark.cli.option_types import int_in, positive_float
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs

Pair = tuple[str, NDArray[np.uint8], NDArray[np.uint8]]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--board", required=True, metavar="SPEC",
                   help="chessboard:CxR:SQUARE (inner corners) or charuco:CxR:SQUARE:MARKER:DICT (squares), metres")
    p.add_argument("images", nargs="*", metavar="LEFT RIGHT", help="stereo pairs: left and right image paths")
    p.add_argument("--source", metavar="SPEC", help="read the views from a frame source (docs/frame_sources.md)")
    p.add_argument("--frames", type=int_in(1, 100000), default=200, metavar="N",
                   help="--source: read at most N frames (default 200)")
    p.add_argument("--layout", choices=("sbs", "tb"), default="sbs",
                   help="--source: how one frame holds both views (side by side, top-bottom)")
    p.add_argument("--every", type=int_in(1, 10000), default=1, metavar="K", help="--source: use every K-th frame")
    p.add_argument("--out", required=True, metavar="FILE.yaml", help="output file: the calibration (project YAML)")
    add_force_argument(p)
    p.add_argument("--report", metavar="DIR", help="write DIR/report.md with per-view errors and pictures")
    p.add_argument("--outlier-floor", type=positive_float(100.0), default=0.5, metavar="PX",
                   help="views are dropped as outliers only above this RMS [px] (default 0.5)")
    p.add_argument("--fix-k3", action="store_true", help="keep k3 = 0 (few views, or a weakly distorting lens)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_json_flag(p)
    set_example(p, "wristmark calibrate --board chessboard:9x6:0.0025 left_1.png right_1.png left_2.png "
                   "right_2.png left_3.png right_3.png --out calib.yaml --report calib_report",
                "wristmark calibrate --board chessboard:9x6:0.0025 --source calib_video.avi --out calib.yaml")


def _file_pairs(paths: list[Path]) -> Iterator[Pair]:
    from wristmark.cvs.sources.images import read_image

    for lp, rp in zip(paths[0::2], paths[1::2]):
        yield f"{lp.name} + {rp.name}", read_image(lp), read_image(rp)


def _source_pairs(spec: str, limit: int, every: int, layout: str) -> Iterator[Pair]:
    from wristmark.cvs.sources.frames import frames
    from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source

    src = open_stereo_source(spec, SourceOptions(layout=layout))
    try:
        for f in frames(src, limit):
            if f.index % every == 0:
                yield f"frame {f.index}", f.left, f.right
    finally:
        src.close()


def run(args: argparse.Namespace) -> int:
    import cv2

    from wristmark.cvs.calibration.board import BoardDetector, BoardSpec
    from wristmark.cvs.calibration.load import save_calibration
    from wristmark.cvs.calibration.stereo import calibrate_stereo, detect_views
    from wristmark.cvs.tracking.warmup import warm_up

    board = BoardSpec.parse(args.board)
    out = Path(args.out)
    if not args.force:  # refuse an existing --out (checked only: written over at the end)
        claim_outputs(files=[out])
    paths = [Path(p) for p in args.images]
    if bool(paths) == bool(args.source):
        raise InputError("give the views either as LEFT RIGHT image pairs or with --source SPEC (not both)")
    if paths:
        if len(paths) % 2:
            raise InputError(f"images come in LEFT RIGHT pairs, got {len(paths)} paths")
        for p in paths:
            if not p.is_file():
                raise InputError(f"{p}: image file not found")
    warm_up(jit=False)  # OpenCV's threads for the whole command (cvs.tracking.warmup)
    example: list[tuple[NDArray[np.uint8], NDArray[np.uint8]]] = []
    detector = BoardDetector(board)

    def keep_first(pairs: Iterator[Pair]) -> Iterator[Pair]:
        for name, left, right in pairs:
            if not example:
                example.append((left, right))
            yield name, left, right

    pairs = _file_pairs(paths) if paths else _source_pairs(args.source, args.frames, args.every, args.layout)
    views = detect_views(keep_first(pairs), detector, total=len(paths) // 2 or None, progress=not args.no_progress)
    res = calibrate_stereo(views, outlier_floor_px=args.outlier_floor, flags=cv2.CALIB_FIX_K3 if args.fix_k3 else 0)
    for v in res.dropped:
        print(f"wristmark calibrate: dropped view {v.name}: {v.reason}", file=sys.stderr)
    save_calibration(out, res.camera)
    if args.report:
        from wristmark.cvs.calibration.report import write_report

        write_report(Path(args.report), res, views, args.board, example[0] if example else None)
    cam = res.camera
    summary = {"out": str(out), "rms_px": res.rms_px, "mono_rms_px": list(res.mono_rms_px),
               "views": len(views), "used": len(views) - len(res.dropped),
               "dropped": [{"view": v.name, "reason": v.reason} for v in res.dropped],
               "fx_px": [float(cam.left.K[0, 0]), float(cam.right.K[0, 0])],
               "fy_px": [float(cam.left.K[1, 1]), float(cam.right.K[1, 1])],
               "baseline_m": cam.baseline,
               "per_view": [{"view": v.name, "left_px": v.left_px, "right_px": v.right_px, "used": v.used}
                            for v in res.views]}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {out}: stereo RMS {res.rms_px:.3f} px over {summary['used']} of {len(views)} views, "
              f"baseline {1000 * cam.baseline:.3f} mm")
    return 0
