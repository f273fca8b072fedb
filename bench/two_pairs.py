"""The two-pair path (cvs.tracking.two_pairs) judged on every two adjacent corners of tracked pairs.

A coded sleeve seen so steeply that each view shows only two X-corners is tracked from those two
stereo pairs and the print (MarkerTracker._retry_two_pairs). Few pairs are that steep, so this
bench asks the path about many more: on stereo pairs of the coded sleeve that the tracker tracks
(the fast renderer, random visible poses, matte and glossy), every two adjacent corners found in
both views are given to it alone, as if no other corner had passed (their edge angles from the
paper's detector). Each chord is kept right (tip within --wrong-mm of the truth and the rotation
within 5 deg), kept wrong, or refused. The path must never be wrong; how many it keeps says how
often two corners suffice. Each tracked pair is also tracked with the box around the sleeve
filled by its blurred background (no marker in view): the tracker must lose it, and the time the
two-pair path adds to such a lost pair is reported (the same tracker with
``two_pairs_min_bars`` 0, the same frames).

    python bench/two_pairs.py --pairs 40 --seed 1
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import replace

import cv2
import numpy as np

from wristmark.cli.render import psi_spread
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.corners.detector import MarkerCornerDetector
from wristmark.cvs.corners.xcorners import XCorners
from wristmark.cvs.gray_image import to_gray
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.cvs.tracking.two_pairs import stereo_chords
from wristmark.cvs.tracking.warmup import warm_up
from wristmark.models.arm_shape import arm_shape
from wristmark.models.arm_spec import load_loop_arm
from wristmark.models.config_files import default_config
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.visibility import random_visible_psi


def _rotation_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_true.T @ R_est) - 1.0) / 2.0, -1.0, 1.0))))


def _with_edges(corners: np.ndarray, chain: XCorners) -> np.ndarray | None:
    """The detector's edge angles (N, 2) of ``corners`` (N, 2) [px], each the chain corner within
    1 px; None if one is not."""
    if not chain.corners.shape[0]:
        return None
    d = np.linalg.norm(corners[:, None, :] - chain.corners[None, :, :], axis=2)
    j = d.argmin(axis=1)
    return None if np.any(d[np.arange(len(j)), j] > 1.0) else chain.edges[j]


def _without_sleeve(view: np.ndarray, corners: np.ndarray, margin_px: float) -> np.ndarray:
    """``view`` (grey) with the box of ``corners`` +- ``margin_px`` [px] filled by the view
    reduced to 60 x 34 and scaled back up."""
    h, w = view.shape[:2]
    bg = cv2.resize(cv2.resize(view, (60, 34), interpolation=cv2.INTER_AREA), (w, h), interpolation=cv2.INTER_LINEAR)
    x0, y0 = np.maximum(np.floor(corners.min(axis=0) - margin_px), 0).astype(int)
    x1, y1 = np.minimum(np.ceil(corners.max(axis=0) + margin_px), [w, h]).astype(int)
    out = view.copy()
    out[y0:y1, x0:x1] = bg[y0:y1, x0:x1]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", type=int, default=40, help="tracked stereo pairs per lighting")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--wrong-mm", type=float, default=0.5, help="a kept tip farther off is wrong [mm]")
    a = ap.parse_args()
    if a.pairs < 1:
        ap.error("--pairs must be >= 1")
    warm_up()
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    params = load_loop_arm(None, marker)
    tracker = MarkerTracker(cam, marker)
    without = MarkerTracker(cam, marker, TrackerSettings(two_pairs_min_bars=0))
    det = MarkerCornerDetector()
    chord_m = 2.0 * marker.radius * math.sin(0.5 * marker.beta)
    report: dict = {"load": os.getloadavg(), "pairs_per_lighting": a.pairs, "seed": a.seed}
    for label, f0, alpha in (("matte", 0.0, 0.1), ("glossy_0.1", 0.04, 0.1)):
        rng = np.random.default_rng(a.seed)
        st = replace(noise_preset("default"), sleeve_specular=f0, sleeve_roughness=alpha, light_offset=0.002)
        renderer = StereoRenderer(cam, marker, st, seed=a.seed)
        counts = {"chords": 0, "kept_right": 0, "kept_wrong": 0, "refused": 0, "pairs_tracked": 0}
        tips: list[float] = []
        rots: list[float] = []
        ms: list[float] = []
        wrong: list[dict] = []
        empty = {"frames": 0, "tracked": 0, "ms": [], "ms_without": []}
        tries = 0
        while counts["pairs_tracked"] < a.pairs and tries < 20 * a.pairs:
            tries += 1
            pair = renderer.render(arm_shape(params, random_visible_psi(params, cam, marker, rng, psi_spread(params),
                                                                        400)))
            tracker.reset()
            r = tracker.track(pair.left, pair.right)
            if not (r.ok and r.roll_known and r.ids_left is not None and r.ids_right is not None):
                continue
            counts["pairs_tracked"] += 1
            views = (to_gray(pair.left), to_gray(pair.right))
            spacing = float(np.median(np.linalg.norm(np.diff(r.corners_left, axis=0), axis=1)))
            blank = (_without_sleeve(views[0], r.corners_left, 4 * spacing),
                     _without_sleeve(views[1], r.corners_right, 4 * spacing))
            for tr, key in ((tracker, "ms"), (without, "ms_without")):
                tr.reset()
                t = time.perf_counter()
                e = tr.track(*blank)
                empty[key].append(1e3 * (time.perf_counter() - t))  # wall time: a lost result's time_ms is its search's
                if key == "ms":
                    empty["frames"] += 1
                    empty["tracked"] += int(e.ok)
            chains = (det.detect(views[0]), det.detect(views[1]))
            by_id = []
            for corners, ids, chain in ((r.corners_left, r.ids_left, chains[0]), (r.corners_right, r.ids_right,
                                                                                    chains[1])):
                xc = XCorners(chain.corners, chain.corners_quadric, chain.polarity, chain.cc, chain.cl, chain.edges)
                e = _with_edges(corners, xc)
                by_id.append({} if e is None else {int(i): (corners[k], e[k]) for k, i in enumerate(ids) if i >= 0})
            n = marker.columns
            for k in sorted(by_id[0]):
                j = (k + 1) % n
                if not (j in by_id[0] and k in by_id[1] and j in by_id[1]):
                    continue
                two = [XCorners(np.stack([v[k][0], v[j][0]]), np.stack([v[k][0], v[j][0]]), np.ones(2, int),
                                np.ones(2), np.ones(2), np.stack([v[k][1], v[j][1]])) for v in by_id]
                chords = [c for c in stereo_chords(tracker.rectifier, [two[0]], [two[1]], chord_m,
                                                   tracker.settings.max_dy_px)
                          if np.allclose(c.uv_right, two[1].corners)]  # the same corners in both views
                for chord in chords:
                    counts["chords"] += 1
                    t = time.perf_counter()
                    kept = tracker.judge_chords(views, [chord])
                    ms.append(1e3 * (time.perf_counter() - t))
                    if not kept:
                        counts["refused"] += 1
                        continue
                    out = kept[0]
                    assert out.tip_left is not None and out.T_left_marker is not None
                    tip = 1e3 * float(np.linalg.norm(out.tip_left - pair.tip_left))
                    rot = _rotation_deg(out.T_left_marker[:3, :3], pair.T_left_marker[:3, :3])
                    if tip > a.wrong_mm or rot > 5.0:
                        counts["kept_wrong"] += 1
                        wrong.append({"ids": [k, j], "tip_mm": tip, "rot_deg": rot})
                    else:
                        counts["kept_right"] += 1
                        tips.append(tip)
                        rots.append(rot)
        report[label] = dict(counts, kept_rate=counts["kept_right"] / max(counts["chords"], 1),
                             tip_mean_mm=float(np.mean(tips)) if tips else None,
                             tip_max_mm=float(np.max(tips)) if tips else None,
                             rot_mean_deg=float(np.mean(rots)) if rots else None,
                             judge_ms_median=float(np.median(ms)) if ms else None, wrong=wrong,
                             no_marker={"frames": empty["frames"], "tracked": empty["tracked"],
                                        "ms_median": float(np.median(empty["ms"])) if empty["ms"] else None,
                                        "ms_median_without_two_pairs": float(np.median(empty["ms_without"]))
                                        if empty["ms_without"] else None})
    report["load_end"] = os.getloadavg()
    print(json.dumps(report, indent=1))
    return 0 if all(report[k]["kept_wrong"] == 0 and report[k]["no_marker"]["tracked"] == 0
                    for k in ("matte", "glossy_0.1")) else 1


if __name__ == "__main__":
    sys.exit(main())
