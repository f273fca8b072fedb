"""Benchmark: several sleeves tracked in one stereo pair (cvs.tracking.arm_set) against each arm alone.

Usage: .venv/bin/python bench/several_arms.py [--scene configs/scenes/two_arms.yaml] [--sequences 20]
       [--pairs 10] [--scale 1.0] [--seed 0] [--spread 0.06] [--alone-background same|other]
       [--by-pair FILE.jsonl] [--save DIR] [--processes]

Rendered scenes (sim.render, 1080p at --scale 1) of the scene's arms in random poses: each
sequence draws, per arm, a random configuration (its tip in a box 1.5 times the scene's cube
around its workspace centre) and another with the tip up to 8 mm away, and moves from one to
the other over ``--pairs`` pairs (ROI tracking from pair to pair, as in a loop);
every arm but the first also has its base moved at random: in half the sequences 50-90 mm
towards the first arm and 10-22 mm in front of or behind it (the arms cross and hide one
another's sleeves), else by up to ``--spread`` [m] along x and 0.02 m along y (depth) and z. Per pair the same
arms are also rendered alone (one arm, one sleeve: the one-arm figure), on the scene's own
background and sensor noise (``--alone-background same``; ``other``: each on another renderer
seed's, as the bench did before 5 December 2026), and tracked by a one-arm MarkerTracker each,
with the arm set's settings (corners only: the one-arm default also fits the print's bars,
cvs.tracking.print_edges, which the arm set does not). Prints JSON:

- ``identity_swaps``: poses reported for an arm that lie nearer another arm's truth (must be 0);
  ``wrong``: reported tips off their own truth by over 0.5 mm (``wrong_alone``: the same for the
  arms rendered and tracked alone, the one-arm tracker's own rate);
- per arm: tracked rate together and alone, tip error mean / max [mm] together and alone (over
  the pairs both tracked), and the pairs where a sleeve had corners hidden by another arm (with
  the tip error means split into the pairs with and without hidden corners);
- ``time_ms``: median tracking time per pair for all sleeves together, the one-arm median per arm
  alone, and their ratio.

One arm-set tracker serves every sequence (``reset()`` between them: a new sequence starts cold),
so that ``--processes`` (every arm but the first in a worker process of its own,
cvs.tracking.arm_set) starts its workers once; without it the arms run in threads of this
process as the arm set decides. The results are the same either way, to the bit; only the times
differ.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.tracking.arm_set import ArmSetTracker
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.cvs.tracking.warmup import warm_up
from wristmark.models.arm_shape import arm_shape, transformed
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.scene_poses import random_tip_psi
from wristmark.sim.scene_setup import load_scene_setup

WRONG_M = 0.0005


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="configs/scenes/two_arms.yaml")
    ap.add_argument("--sequences", type=int, default=20)
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spread", type=float, default=0.06)
    ap.add_argument("--alone-background", choices=("same", "other"), default="same",
                    help="the arms alone on the scene's background and noise (same, default) or on another "
                         "renderer seed's each (other: the bench before 5 December 2026)")
    ap.add_argument("--by-pair", default="", help="write one JSON line per pair and arm to this file (sequence, "
                    "pair, tracked, tip errors together / alone [mm], hidden corners)")
    ap.add_argument("--processes", action="store_true", help="track every arm but the first in a worker process "
                    "of its own (ArmSetTracker(processes=True)) instead of threads")
    ap.add_argument("--save", default="", help="save the scene images and truths of each sequence with a pose "
                    "over 0.5 mm off or 0.1 mm worse than alone to DIR/seq_NN.npz (to replay them)")
    args = ap.parse_args()
    warm_up()
    setup = load_scene_setup(args.scene)
    names = setup.names
    cam = scaled_stereo_camera(setup.camera, args.scale) if args.scale != 1.0 else setup.camera
    markers = setup.markers
    together_r = StereoRenderer(cam, markers, RenderSettings(), seed=args.seed)
    # 'same': each arm alone on the scene's own background and sensor noise (its renderer's seed and
    # call count are the scene renderer's), so that together and alone differ by the other arms only
    alone_seeds = [args.seed if args.alone_background == "same" else args.seed + 1 + i for i in range(len(markers))]
    alone_r = [StereoRenderer(cam, m, RenderSettings(), seed=sd) for m, sd in zip(markers, alone_seeds)]
    rng = np.random.default_rng(args.seed)
    stats: dict[str, dict[str, Any]] = {n: {"together": [], "alone": [], "hidden": [], "occluded_pairs": 0, "n": 0,
                                            "tracked_together": 0, "tracked_alone": 0} for n in names}
    swaps = wrong = wrong_alone = 0
    t_together: list[float] = []
    t_alone: list[float] = []
    rows: list[dict[str, Any]] = []
    scene_trk = ArmSetTracker(cam, markers, processes=args.processes)  # closed below (or at exit)
    for seq in range(args.sequences):
        scene_trk.reset()
        # each arm alone with the arm set's own settings (corners only, no print bars:
        # cvs.tracking.arm_set), so that together and alone differ by the other arms only
        alone_trk = [MarkerTracker(cam, m, scene_trk.settings, family=markers) for m in markers]
        bases = []
        for i, n in enumerate(names):
            B = setup.base(n).copy()
            if i > 0 and rng.uniform() < 0.5:  # crossing: towards the first arm, in front of or behind it
                toward = -np.sign(B[0, 3] - setup.base(names[0])[0, 3]) if i == 1 else rng.choice([-1.0, 1.0])
                B[:3, 3] += [toward * rng.uniform(0.05, 0.09), rng.choice([-1.0, 1.0]) * rng.uniform(0.01, 0.022),
                             rng.uniform(-0.012, 0.012)]
            elif i > 0:
                B[:3, 3] += [rng.uniform(-args.spread, args.spread), rng.uniform(-0.02, 0.02),
                             rng.uniform(-0.02, 0.02)]
            bases.append(B)
        size = setup.scene.cube_size
        starts = [random_tip_psi(setup.arms[n].params, size, rng) for n in names]
        ends = [(q, random_tip_psi(setup.arms[n].params, size, rng, near=q)) for n, q in zip(names, starts)]
        saved: list[Any] = []
        for k in range(args.pairs):
            f = k / max(1, args.pairs - 1)
            shapes = [transformed(arm_shape(setup.arms[n].params, (1 - f) * ends[i][0] + f * ends[i][1]), bases[i])
                      for i, n in enumerate(names)]
            scene = together_r.render_arms(shapes)
            t0 = time.perf_counter()
            res = scene_trk.track(scene.left, scene.right)
            t_together.append(1000 * (time.perf_counter() - t0))
            if args.save:
                saved.append(scene)
            for i, n in enumerate(names):
                st = stats[n]
                st["n"] += 1
                truth = scene.arms[i]
                hidden = any(c.occluded for c in truth.corners_left + truth.corners_right)
                st["occluded_pairs"] += int(hidden)
                alone = alone_r[i].render(shapes[i])
                t1 = time.perf_counter()
                ra = alone_trk[i].track(alone.left, alone.right)
                t_alone.append(1000 * (time.perf_counter() - t1))
                ok_alone = ra.ok and ra.code is not None and ra.code.arm == n
                st["tracked_alone"] += int(ok_alone)
                if ok_alone and ra.tip_left is not None:
                    wrong_alone += int(float(np.linalg.norm(ra.tip_left - alone.tip_left)) > WRONG_M)
                r = res[n]
                ea = float(np.linalg.norm(ra.tip_left - alone.tip_left)) if ok_alone and ra.tip_left is not None \
                    else None
                et = float(np.linalg.norm(r.tip_left - truth.tip_left)) if r.ok and r.tip_left is not None else None
                rows.append({"sequence": seq, "pair": k, "arm": n, "hidden": hidden, "reason": r.reason,
                             "tip_mm_together": None if et is None else 1000 * et,
                             "tip_mm_alone": None if ea is None else 1000 * ea})
                if r.ok and r.tip_left is not None:
                    st["tracked_together"] += 1
                    e = float(np.linalg.norm(r.tip_left - truth.tip_left))
                    others = [float(np.linalg.norm(r.tip_left - scene.arms[j].tip_left))
                              for j in range(len(names)) if j != i]
                    swaps += int(bool(others) and min(others) < e)
                    wrong += int(e > WRONG_M)
                    if ok_alone and ra.tip_left is not None:
                        st["together"].append(e)
                        st["alone"].append(float(np.linalg.norm(ra.tip_left - alone.tip_left)))
                        st["hidden"].append(hidden)
        if args.save and any(r["sequence"] == seq and r["tip_mm_together"] is not None and (
                r["tip_mm_together"] > 1000 * WRONG_M or r["tip_mm_together"] > (r["tip_mm_alone"] or 0.0) + 0.1)
                for r in rows):
            _save(f"{args.save}/seq_{seq:02d}.npz", saved)
    scene_trk.close()
    out: dict[str, Any] = {"scene": args.scene, "pairs": args.sequences * args.pairs, "scale": args.scale,
                           "image_size": list(cam.image_size), "identity_swaps": swaps, "wrong": wrong,
                           "wrong_alone": wrong_alone, "alone_background": args.alone_background,
                           "processes": bool(args.processes), "arms": {}}
    for n, st in stats.items():
        tg, al = np.array(st["together"]) * 1000, np.array(st["alone"]) * 1000
        hid = np.array(st["hidden"], bool)
        out["arms"][n] = {
            "tracked_together": st["tracked_together"], "tracked_alone": st["tracked_alone"], "pairs": st["n"],
            "pairs_with_hidden_corners": st["occluded_pairs"],
            "tip_mean_mm_together": float(tg.mean()) if tg.size else None,
            "tip_mean_mm_alone": float(al.mean()) if al.size else None,
            "tip_max_mm_together": float(tg.max()) if tg.size else None,
            "tip_max_mm_alone": float(al.max()) if al.size else None,
            "both_tracked": int(tg.size),
            "with_hidden_corners": _split(tg[hid], al[hid]),
            "without_hidden_corners": _split(tg[~hid], al[~hid]),
        }
    med_t, med_a = float(np.median(t_together)), float(np.median(t_alone))
    out["time_ms"] = {"together_median": med_t, "one_arm_median": med_a, "ratio": med_t / med_a}
    print(json.dumps(out, indent=1))
    if args.by_pair:
        with open(args.by_pair, "w") as f:
            f.writelines(json.dumps(row) + "\n" for row in rows)


def _save(path: str, scenes: list[Any]) -> None:
    """A sequence's scene images, true tips [m] and true corners [px] (with their occlusion flags)."""
    np.savez_compressed(
        path, left=np.stack([s.left for s in scenes]), right=np.stack([s.right for s in scenes]),
        tips=np.array([[a.tip_left for a in s.arms] for s in scenes]),
        corners=np.array([[[[c.uv for c in a.corners_left], [c.uv for c in a.corners_right]] for a in s.arms]
                          for s in scenes]),
        occluded=np.array([[[[c.occluded for c in a.corners_left], [c.occluded for c in a.corners_right]]
                            for a in s.arms] for s in scenes]))


def _split(together: np.ndarray, alone: np.ndarray) -> dict[str, Any]:
    """Tip error means [mm] together and alone over a subset of the pairs both tracked."""
    return {"pairs": int(together.size), "tip_mean_mm_together": float(together.mean()) if together.size else None,
            "tip_mean_mm_alone": float(alone.mean()) if alone.size else None}


if __name__ == "__main__":
    main()
