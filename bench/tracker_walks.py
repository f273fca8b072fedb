"""The tracker on rendered walks of an arm, two or more tracker settings side by side.

Usage: python bench/tracker_walks.py --compare {facing,chain_polarity,tip_sigma,bars_gate,partners,
           reduced,stereo_dy,single_view,wide_windows,two_pairs,blur_fit,small_fit,
           reduced_noise,refine_window} [--robot tendon3] [--marker FILE]
           [--image-scale 0.25] [--walks 20] [--first-walk 0] [--frames 40] [--spread 0.02]
           [--wide] [--wrong-mm 1.5]
Prints JSON. Each walk starts at the arm's home plus a seeded offset of ``--spread`` [rad or m]
per joint (``--wide``: anywhere within the joint limits where both cameras see the marker: steep
and small views too) and drifts from there (a tenth of the spread per frame, as a slow servo walk), with
the endoscope framed for the arm (sim.setup) at ``--image-scale``; every pair is rendered, JPEG
coded (quality 90, as the virtual endoscope sends it) and tracked in sequence with the model's
marker axis as the hint (as the servo loop does; ROI tracking from pair to pair) by one tracker
per variant, in the same loop: tracked rate, wrong (tip more than ``--wrong-mm`` off the truth),
tip error mean and max [mm], median time per pair [ms] (noisy: compare the ratio).

Comparisons:
  facing          without the sleeve-facing check (``min_corner_facing`` -inf) and the default
                  (cvs.tracking.sleeve_facing, docs/notes/sleeve-facing.md);
  chain_polarity  the chain's corners alternating in the X-corner test's own polarity (the
                  paper's; ``chain_polarity: image``, no cross-edge test) against the polarity
                  along the chain (the default), and that with the enlarged search of a lost
                  pair (``magnify`` 2; docs/notes/steep-views.md);
  tip_sigma       without the gate on the tip's standard deviation (``max_tip_sigma_m`` inf)
                  and the default (cvs.tracking.tip_uncertainty);
  bars_gate       a fit refused by that gate kept as refused (``bars_gate`` false) and the
                  default, which weighs the print's bars in (MarkerTracker._retry_with_bars);
  partners        a fit refused as hinging on single-view corners kept as refused
                  (``partner_max_px`` 0) and the default, which looks for their partners in the
                  other view (MarkerTracker._retry_partners);
  reduced         a pair still lost not searched again (``reduced_scales`` empty) and the
                  default, which searches each whole view reduced 2, 3 and 4 times and fits the
                  corners found there on the view itself (MarkerTracker._retry_reduced);
  stereo_dy       left and right corners paired within 2 px of rectified y and within 2.5 px
                  (``max_dy_px``; cvs.tracking.stereo_match);
  single_view     a corner seen by one camera only held to the pose solve's usual outlier test
                  (``PoseSettings.single_view_factor`` 0) and the default, which holds it to a
                  stricter one (2 x the median residual instead of 4);
  wide_windows    a fit the contrast gate refused kept as refused (``wide_sigma_px`` 0) and the
                  default, which fits its corners again in windows matched to their spacing where
                  they lie more than ~33 px apart (MarkerTracker._retry_wide_windows);
  two_pairs       a coded sleeve's pair still lost kept lost (``two_pairs_min_bars`` 0) and the
                  default, which tries its views' chains of two corners in every roll hypothesis
                  (MarkerTracker._retry_two_pairs; needs ``--marker configs/marker_coded.yaml``).
  blur_fit        bar edges by the largest gradient alone (``edge_blur_fit_px`` 0) and the
                  default, where a blurred edge the gradient refuses is measured by a fitted
                  blurred step (print_edges.measure_edges);
  small_fit       a fit whose corners are under 23 px apart judged by the tip-sigma gate
                  alone (``max_small_fit_tip_sigma_m`` inf), the default, which also holds it to
                  its residual (MarkerTracker._small_fit_sigma), and the default with the
                  enlarged search of a lost pair (``magnify`` 2; docs/notes/steep-views.md);
  reduced_noise   the reduced search's corners counted as the first search's, 1 px beside
                  clipped pixels (``reduced_sigma_px`` 0), and the default, where a reduced fit
                  that passes only at their measured 0.5 px is the pair's last resort
                  (MarkerTracker._last_resort; docs/notes/highlight-stripe.md).
  refine_window   the paper detector's HTM fit in a 9 x 9 window for every corner
                  (``refine_window_sigmas`` 0, before stop 69), and the default, in a window
                  of at least 1.5 sigma of its Gaussian weights (13 x 13 for corners 28 px or
                  more apart; docs/notes/highlight-stripe.md).
"""

from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np

from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.corners.xcorners import DetectorSettings
from wristmark.cvs.tracking.stereo_pose import PoseSettings
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings
from wristmark.cvs.tracking.warmup import warm_up
from wristmark.models.arm_spec import home_psi
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import clamp_psi, psi_bounds
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.setup import load_setup, make_plant
from wristmark.sim.visibility import random_visible_psi

COMPARISONS: dict[str, dict[str, TrackerSettings]] = {
    "facing": {"without_facing_check": TrackerSettings(min_corner_facing=-np.inf), "default": TrackerSettings()},
    "chain_polarity": {
        "image_polarity": TrackerSettings(
            paper_detector=DetectorSettings(chain_polarity="image", cross_edge_tol_deg=90.0), magnify=1.0),
        "default": TrackerSettings(),
        "magnified": TrackerSettings(magnify=2.0),
    },
    "tip_sigma": {"without_tip_sigma_gate": TrackerSettings(max_tip_sigma_m=np.inf), "default": TrackerSettings()},
    "bars_gate": {"without_bars_gate": TrackerSettings(bars_gate=False), "default": TrackerSettings()},
    "partners": {"without_partners": TrackerSettings(partner_max_px=0.0), "default": TrackerSettings()},
    "reduced": {"without_reduced": TrackerSettings(reduced_scales=()), "default": TrackerSettings()},
    "stereo_dy": {"max_dy_2px": TrackerSettings(max_dy_px=2.0), "max_dy_2.5px": TrackerSettings(max_dy_px=2.5)},
    "single_view": {"usual_test": TrackerSettings(pose=PoseSettings(single_view_factor=0.0)),
                    "default": TrackerSettings()},
    "wide_windows": {"without_wide_windows": TrackerSettings(wide_sigma_px=0.0), "default": TrackerSettings()},
    "two_pairs": {"without_two_pairs": TrackerSettings(two_pairs_min_bars=0), "default": TrackerSettings()},
    "blur_fit": {"without_blur_fit": TrackerSettings(edge_blur_fit_px=0.0), "default": TrackerSettings()},
    "small_fit": {"without_small_fit_gate": TrackerSettings(max_small_fit_tip_sigma_m=np.inf),
                  "default": TrackerSettings(), "magnified": TrackerSettings(magnify=2.0)},
    "reduced_noise": {"clipped_model": TrackerSettings(reduced_sigma_px=0.0), "default": TrackerSettings()},
    "refine_window": {"window_9x9": TrackerSettings(paper_detector=DetectorSettings(refine_window_sigmas=0.0)),
                      "default": TrackerSettings()},
}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--compare", choices=sorted(COMPARISONS), required=True)
    ap.add_argument("--robot", default="tendon3", help="a shipped arm (configs/robots/NAME.yaml)")
    ap.add_argument("--marker", default=None, help="a marker file (default: the arm's own, configs/marker.yaml)")
    ap.add_argument("--image-scale", type=float, default=0.25)
    ap.add_argument("--walks", type=int, default=20)
    ap.add_argument("--first-walk", type=int, default=0, help="the first walk's seed (walks are seeded in turn)")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--spread", type=float, default=0.02)
    ap.add_argument("--wrong-mm", type=float, default=1.5)
    ap.add_argument("--wide", action="store_true", help="walks start anywhere within the joint limits (marker in view)")
    args = ap.parse_args()
    warm_up()
    setup = load_setup(robot=CONFIG_DIR / "robots" / f"{args.robot}.yaml", marker=args.marker)
    render_cam = scaled_stereo_camera(setup.render_camera, args.image_scale)
    cam = scaled_stereo_camera(setup.tracking_camera, args.image_scale)
    W = cam.T_world_left
    assert W is not None
    variants = COMPARISONS[args.compare]
    stats: dict[str, dict[str, list[float]]] = {k: {"err": [], "ms": []} for k in variants}
    pairs = 0
    h = home_psi(setup.params)
    for walk in range(args.first_walk, args.first_walk + args.walks):
        rng = np.random.default_rng(walk)
        if args.wide:
            lo, hi = psi_bounds(setup.params)
            psi = random_visible_psi(setup.params, cam, setup.marker, rng, tuple(np.minimum(0.5 * (hi - lo), np.pi)))
        else:
            psi = h + rng.normal(0.0, args.spread, h.size)
        renderer = StereoRenderer(render_cam, setup.marker, noise_preset("default"), seed=walk)
        trackers = {k: MarkerTracker(cam, setup.marker, s) for k, s in variants.items()}
        for _ in range(args.frames):
            psi = clamp_psi(setup.params, psi + rng.normal(0.0, 0.1 * args.spread, h.size))
            shape = make_plant(setup, psi).true_shape()
            pair = renderer.render(shape)
            left, right = (cv2.imdecode(cv2.imencode(".jpg", im, [cv2.IMWRITE_JPEG_QUALITY, 90])[1],
                                        cv2.IMREAD_UNCHANGED) for im in (pair.left, pair.right))
            hint = W[:3, :3].T @ forward_kinematics(setup.params, psi).T_world_marker[:3, 2]
            pairs += 1
            for k, trk in trackers.items():
                t0 = time.perf_counter()
                res = trk.track(left, right, axis_hint_left=hint)
                stats[k]["ms"].append(1e3 * (time.perf_counter() - t0))
                if res.ok and res.tip_left is not None:
                    stats[k]["err"].append(1e3 * float(np.linalg.norm(W[:3, :3] @ res.tip_left + W[:3, 3] - shape.tip)))
    out: dict[str, object] = {"compare": args.compare, "robot": args.robot, "image_scale": args.image_scale,
                              "marker": args.marker, "pairs": pairs, "walks": args.walks, "first_walk": args.first_walk,
                              "spread": args.spread, "wide": args.wide,
                              "wrong_mm": args.wrong_mm}
    for k, s in stats.items():
        e = np.array(s["err"])
        out[k] = {"tracked_pct": round(100.0 * e.size / pairs, 1), "wrong": int((e > args.wrong_mm).sum()),
                  "err_mean_mm": round(float(e.mean()), 3) if e.size else None,
                  "err_max_mm": round(float(e.max()), 2) if e.size else None,
                  "median_ms": round(float(np.median(s["ms"])), 2)}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
