"""Real-photo benchmark of our X-corner stage against cv2.findChessboardCornersSB: prints JSON.

Usage: python bench/real_chessboard.py [FOLDER]
FOLDER holds OpenCV's stereo samples leftNN.jpg / rightNN.jpg (default tests/data/opencv_stereo,
13 pairs, 9x6 inner corners). Per image: complete 9x6 grids found, time, mean distance between
our corners (cvs.corners.detector.detect_xcorners + assemble_grid) and OpenCV's (same order);
then cv2.stereoCalibrate reprojection RMS [px] from each method's corners (each camera calibrated
alone first, then CALIB_USE_INTRINSIC_GUESS). Ours is run twice: with the HTM refinement (default)
and with the paper's eq. 9-10 quadric only (refine=False).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from wristmark.cvs.corners.detector import BOARD_SETTINGS, assemble_grid, detect_xcorners  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402

PATTERN = (9, 6)


def _stereo(left: list, right: list, size: tuple[int, int]) -> dict[str, Any]:
    keep = [k for k in range(len(left)) if left[k] is not None and right[k] is not None]
    if len(keep) < 3:
        return {"pairs_used": len(keep), "rms_px": None}
    objp = np.zeros((PATTERN[0] * PATTERN[1], 3), np.float32)
    objp[:, :2] = np.mgrid[0 : PATTERN[0], 0 : PATTERN[1]].T.reshape(-1, 2)
    obj = [objp] * len(keep)
    L = [np.asarray(left[k], np.float32).reshape(-1, 1, 2) for k in keep]
    R = [np.asarray(right[k], np.float32).reshape(-1, 1, 2) for k in keep]
    rl, K1, D1, _, _ = cv2.calibrateCamera(obj, L, size, None, None)
    rr, K2, D2, _, _ = cv2.calibrateCamera(obj, R, size, None, None)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-6)
    rms, *_, T, _, _ = cv2.stereoCalibrate(
        obj, L, R, K1, D1, K2, D2, size, flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=crit
    )
    return {
        "pairs_used": len(keep),
        "rms_px": float(rms),
        "mono_rms_px": [float(rl), float(rr)],
        "T_squares": np.asarray(T, float).ravel().round(4).tolist(),
    }


def _opencv_sb(g: np.ndarray) -> np.ndarray | None:
    ok, c = cv2.findChessboardCornersSB(g, PATTERN, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    return c.reshape(-1, 2).astype(np.float64) if ok else None


def run(folder: Path) -> dict[str, Any]:
    names = sorted(p.stem[4:] for p in folder.glob("left*.jpg"))
    methods = {
        "ours": lambda g: assemble_grid(detect_xcorners(g), PATTERN, g),
        "ours_eq10_quadric_only": lambda g: assemble_grid(
            detect_xcorners(g, replace(BOARD_SETTINGS, refine=False)), PATTERN, g
        ),
        "opencv_sb": _opencv_sb,
    }
    corners: dict[str, dict[str, list]] = {m: {"left": [], "right": []} for m in methods}
    times: dict[str, list[float]] = {m: [] for m in methods}
    size = (0, 0)
    for n in names:
        for side in ("left", "right"):
            g = cv2.imread(str(folder / f"{side}{n}.jpg"), cv2.IMREAD_GRAYSCALE)
            size = (g.shape[1], g.shape[0])
            for m, fn in methods.items():
                t0 = time.perf_counter()
                corners[m][side].append(fn(g))
                times[m].append(1e3 * (time.perf_counter() - t0))
    out: dict[str, Any] = {"folder": str(folder), "pairs": len(names), "pattern": list(PATTERN)}
    for m in methods:
        found = sum(c is not None for s in corners[m].values() for c in s)
        res: dict[str, Any] = {
            "grids_found": found,
            "images": 2 * len(names),
            "ms_per_image_median": float(np.median(times[m])),
        }
        if m != "opencv_sb":
            d = [
                float(np.mean(np.hypot(*(a - b).T)))
                for s in ("left", "right")
                for a, b in zip(corners[m][s], corners["opencv_sb"][s])
                if a is not None and b is not None
            ]
            res["mean_dist_to_opencv_px_per_image"] = np.round(d, 3).tolist()
            res["mean_dist_to_opencv_px_max"] = max(d) if d else None
        res["stereo_calibrate"] = _stereo(corners[m]["left"], corners[m]["right"], size)
        out[m] = res
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", default=str(Path(__file__).resolve().parents[1] / "tests/data/opencv_stereo"))
    a = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    print(json.dumps(run(Path(a.folder)), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
