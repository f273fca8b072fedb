"""The tracker on path-traced stereo pairs (Mitsuba 3, ``--engine pbr``) that the tests never saw.

Usage: python bench/pbr_tracking.py [--pairs N] [--seed S] [--image-scale F] [--spp N] [--cache DIR] [--only I,J]
           [--loop-hint] [--baseline KEY=VALUE ...]
Needs the extra 'pbr' (scripts/ensure-pbr.sh). Prints JSON. Per pair, drawn from ``--seed``
(not the committed set's poses, tests/data/pbr): the sleeve (reference and coded in turn), a
visible configuration (every other one with the sleeve within 5 deg of square to the line of
sight, where the coaxial highlight runs along it), the laminate's GGX roughness (log-uniform
0.03-0.3, F0 0.04), the light outputs' offset beside the lenses (0-3 mm), the thin lens
(aperture radius 0-0.4 mm, focus 60-100 mm) and the sensor noise (the default, JPEG 90).
Each pair is tracked cold by today's tracker (the paper's chain only: detector ``max_gaps`` 0)
and by the default one (a lost pair retried with chains that step over a washed-out corner), in
the same loop (``--baseline KEY=VALUE``, repeated: today's tracker is instead the default one
with these TrackerSettings fields, VALUE in JSON, e.g. ``--baseline reduced_scales=[]``,
``--baseline max_dy_px=2.0`` or, for a field of a settings group, ``--baseline axis.arm_offsets=[]``:
an A/B of one setting on the same pairs): tracked rate, wrong (tip
more than ``--wrong-mm`` off), tip error mean [mm], the coded sleeve's roll-known rate and
rotation error mean [deg], median time [ms], and the tracked tips' errors over their own
reported sigma (``TrackResult.tip_sigma_m``: median, 99th percentile, largest, how many beyond
3, how many without one), and the default tracker's corners at the truth (``corner_errors``: each
used corner's distance from the nearest of the true pose's projected ring corners, by the search
whose fit was kept, first, gap, reduced or eroded, and by whether a clipped pixel lies within
``clipped_radius`` times the chain's spacing; with the solve's own noise for them).
``--loop-hint`` gives the trackers the marker's true axis as the direction hint, as the servo loop
gives the commanded model's. ``--cache DIR`` keeps the rendered pairs, so a tracker change is
measured again on the same pairs without rendering (about 5 s a pair at half size, 25 s at 1080p
here).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, is_dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.render import psi_spread
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.gray_image import to_gray
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tip_uncertainty import near_clipped
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.cvs.tracking.warmup import warm_up
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.render.pbr import PbrSettings, PbrStereoRenderer, load_mitsuba
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.visibility import random_visible_psi

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pbr_pool import corner_summary  # noqa: E402 - the pooled report's own summary of the corners


def _tilt_deg(T: np.ndarray) -> float:
    o, z = T[:3, 3], T[:3, 2]
    return float(np.degrees(np.arcsin(min(1.0, abs(float(z @ o)) / float(np.linalg.norm(o))))))


def _rotation_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_true.T @ R_est) - 1.0) / 2.0, -1.0, 1.0))))


def _honesty(ok: list[dict]) -> dict[str, Any]:
    """The tracked tips' errors over their own reported sigma (TrackResult.tip_sigma_m): median,
    99th percentile and largest, how many are more than 3 of it off, and how many have no sigma."""
    z = np.array([o["tip_mm"] / o["sigma_mm"] for o in ok if o.get("sigma_mm")])
    out: dict[str, Any] = {"median": None, "p99": None, "max": None, "beyond_3": 0}
    if z.size:
        out = {"median": float(np.median(z)), "p99": float(np.percentile(z, 99)), "max": float(z.max()),
               "beyond_3": int((z > 3.0).sum())}
    return out | {"without_sigma": sum(not o.get("sigma_mm") for o in ok)}


# the searches whose kept fits carry a timings key of their own (the first search: none of them)
_SEARCHES = (("reduced", "reduced_refit"), ("eroded", "eroded_refit"), ("gap", "gap_chain_fit"))


def _corner_errors(tr: MarkerTracker, r: Any, pair: Any) -> list[dict[str, Any]]:
    """Each used corner of a good result ``r``: its search, whether it is near a clipped pixel,
    its error (x, y) [px] from the nearest ring corner of the true pose, and the solve's noise [px]."""
    m, pose = r.match, r.pose
    if not r.ok or m is None or pose is None:
        return []
    search = next((name for name, key in _SEARCHES if key in r.timings), "first")
    s = tr.settings
    ring = tr.solver.marker_points(np.arange(tr.marker.columns))
    T = np.asarray(pair.T_left_marker, float)
    spacing = float(np.median(np.concatenate([np.hypot(*np.diff(c, axis=0).T) for c in (r.corners_left,
                                                                                          r.corners_right)])))
    out = []
    for k, (corners, index, inliers, project, view) in enumerate((
            (r.corners_left, m.index_left, pose.inliers_left, tr.camera.project_left, pair.left),
            (r.corners_right, m.index_right, pose.inliers_right, tr.camera.project_right, pair.right))):
        used = np.asarray(inliers, bool)
        uv = corners[index >= 0][used]
        if not len(uv):
            continue
        true = np.asarray(project(ring @ T[:3, :3].T + T[:3, 3]), float).reshape(-1, 2)
        err = uv - true[np.linalg.norm(uv[:, None] - true[None], axis=2).argmin(1)]
        near = near_clipped(to_gray(view), uv, s.clipped_radius * spacing, s.clipped_level)
        noise = (np.full(len(uv), np.nan) if r.corner_sigmas is None else np.asarray(r.corner_sigmas[k])[used])
        out += [{"search": search, "near_clipped": bool(n), "error_px": [round(float(e[0]), 4), round(float(e[1]), 4)],
                 "solve_sigma_px": round(float(g), 4)} for e, n, g in zip(err, near, noise)]
    return out


@dataclass(frozen=True)
class _Pair:
    left: np.ndarray
    right: np.ndarray
    tip_left: np.ndarray
    T_left_marker: np.ndarray


def _rendered(cache: str | None, i: int, renderer: Callable[[], Any], shape: Any) -> Any:
    """Pair ``i``: from ``cache`` where it was kept, else rendered by a renderer that ``renderer``
    builds (and kept there); a cached pair builds no renderer (no Mitsuba scene set-up)."""
    if cache is None:
        return renderer().render(shape)
    path = Path(cache) / f"pair_{i}.npz"
    if path.is_file():
        with np.load(path) as z:
            return _Pair(z["left"], z["right"], z["tip_left"], z["T_left_marker"])
    pair = renderer().render(shape)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, left=pair.left, right=pair.right, tip_left=pair.tip_left,
                        T_left_marker=pair.T_left_marker)
    return pair


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", type=int, default=60)
    ap.add_argument("--seed", type=int, default=101)
    ap.add_argument("--image-scale", type=float, default=0.5)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--wrong-mm", type=float, default=0.5)
    ap.add_argument("--cache", metavar="DIR",
                    help="keep each rendered pair in DIR (pair_<i>.npz) and track those already there again "
                         "instead of rendering them (the same --pairs, --seed, --image-scale and --spp)")
    ap.add_argument("--only", metavar="I,J,...",
                    help="render and track only these pairs (0-based indices below --pairs; every pair is still "
                         "drawn, so each is the same pair as in a full run): a lost pair looked at again")
    ap.add_argument("--loop-hint", action="store_true",
                    help="give both trackers the marker's true axis as the direction hint, as the servo loop gives "
                         "the commanded model's (a reference sleeve's direction then comes from it)")
    ap.add_argument("--baseline", metavar="KEY=VALUE", action="append", default=[],
                    help="today's tracker is the default one with this TrackerSettings field, or GROUP.FIELD of a "
                         "settings group such as axis.arm_offsets (VALUE in JSON; repeat for more), instead of the "
                         "paper's chain alone")
    a = ap.parse_args()
    overrides: dict[str, Any] = {}
    given: dict[str, Any] = {}  # as given, for the report (KEY or GROUP.FIELD: the JSON value)
    nested: dict[str, dict[str, Any]] = {}
    defaults = TrackerSettings()
    for item in a.baseline:
        key, sep, value = item.partition("=")
        group, dot, field = key.partition(".")
        sub = getattr(defaults, group, None) if dot else None
        known = (group in TrackerSettings.__dataclass_fields__ if not dot else
                 is_dataclass(sub) and field in sub.__dataclass_fields__)
        if not sep or not known:
            ap.error(f"--baseline: KEY=VALUE with KEY a TrackerSettings field or GROUP.FIELD (e.g. axis.arm_offsets), "
                     f"not {item!r}")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            ap.error(f"--baseline {key}: VALUE in JSON (e.g. 2.0, [], true), not {value!r}")
        given[key] = parsed
        parsed = tuple(parsed) if isinstance(parsed, list) else parsed
        if dot:
            nested.setdefault(group, {})[field] = parsed
        else:
            overrides[key] = parsed
    try:
        for group, fields in nested.items():
            overrides[group] = replace(overrides.get(group, getattr(defaults, group)), **fields)
        baseline = TrackerSettings(**overrides) if overrides else None
    except (InputError, TypeError, ValueError) as e:
        ap.error(f"--baseline: {e}")
    try:
        only = None if a.only is None else {int(v) for v in a.only.split(",") if v.strip()}
    except ValueError:
        ap.error(f"--only: comma-separated pair indices, not {a.only!r}")
    if only is not None and (not only or min(only) < 0 or max(only) >= a.pairs):
        ap.error(f"--only: indices from 0 to {a.pairs - 1} (--pairs {a.pairs})")
    wanted = range(a.pairs) if only is None else sorted(only)
    if a.cache is None or not all((Path(a.cache) / f"pair_{i}.npz").is_file() for i in wanted):
        load_mitsuba()  # a pair to render: Mitsuba is needed (a one-line error before the warm-up)
    warm_up()
    full = load_calibration(str(default_config("camera.yaml")))
    cam = scaled_stereo_camera(full, a.image_scale) if a.image_scale != 1 else full
    P = RobotParams()
    rng = np.random.default_rng(a.seed)
    sleeves = {"reference": MarkerModel(), "coded": MarkerModel.load(default_config("marker_coded.yaml"))}
    trackers = {}
    for name, m in sleeves.items():
        today, ours = MarkerTracker(cam, m, baseline), MarkerTracker(cam, m)
        if baseline is None:
            for d in (today.detector_left, today.detector_right):
                d.settings = replace(d.settings, max_gaps=0)  # type: ignore[attr-defined]
        trackers[name] = {"today": today, "default": ours}
    T_lw = np.linalg.inv(np.asarray(cam.T_world_left, float))
    rows: list[dict] = []
    t_start = time.time()
    for i in range(a.pairs):
        name = ("reference", "coded")[i % 2]
        m = sleeves[name]
        while True:
            q = random_visible_psi(P, cam, m, rng, psi_spread(P), 400)
            if (i // 2) % 2 == 1 or _tilt_deg(T_lw @ arm_shape(P, q).T_world_marker) <= 5.0:
                break
        pbr = PbrSettings(spp=a.spp, sleeve_specular=0.04, sleeve_roughness=float(np.exp(rng.uniform(np.log(0.03),
                                                                                               np.log(0.3)))),
                          light_offset=float(rng.uniform(0, 0.003)), aperture_radius=float(rng.uniform(0, 4e-4)),
                          focus_distance=float(rng.uniform(0.06, 0.1)))
        seed = a.seed * 1000 + i
        if only is not None and i not in only:
            continue
        pair = _rendered(a.cache, i, partial(PbrStereoRenderer, cam, m, noise_preset("default", jpeg_quality=90), pbr,
                                             seed=seed), arm_shape(P, q))
        row: dict = {"pair": i, "sleeve": name, "roughness": pbr.sleeve_roughness, "light_offset": pbr.light_offset,
                     "aperture": pbr.aperture_radius, "focus": pbr.focus_distance,
                     "tilt_deg": _tilt_deg(pair.T_left_marker)}
        for k, tr in trackers[name].items():
            tr.reset()
            r = tr.track(pair.left, pair.right, axis_hint_left=pair.T_left_marker[:3, 2] if a.loop_hint else None)
            out = {"ok": r.ok, "reason": r.reason, "ms": r.time_ms, "roll_known": r.roll_known, "rms_px": r.rms_px,
                   "retried": "gap_chain" in r.timings,
                   "pairs": None if r.match is None else r.match.n_pairs}
            if r.ok and r.tip_left is not None and r.T_left_marker is not None:
                out["tip_mm"] = 1e3 * float(np.linalg.norm(r.tip_left - pair.tip_left))
                out["rot_deg"] = _rotation_deg(r.T_left_marker[:3, :3], pair.T_left_marker[:3, :3])
                out["sigma_mm"] = 1e3 * r.tip_sigma_m if np.isfinite(r.tip_sigma_m) else None
                if k == "default":  # its used corners at the truth
                    out["corners"] = _corner_errors(tr, r, pair)
            row[k] = out
        rows.append(row)
    report: dict = {"pairs": len(rows), "image_size": list(cam.image_size), "spp": a.spp, "seed": a.seed,
                    "loop_hint": a.loop_hint,
                    "render_s": time.time() - t_start, "load": os.getloadavg(),
                    "today_is": given if given else "the paper's chain alone (detector max_gaps 0)"}
    for k in ("today", "default"):
        ok = [r[k] for r in rows if r[k]["ok"]]
        tips = [o["tip_mm"] for o in ok]
        coded = [r[k] for r in rows if r["sleeve"] == "coded"]
        known = [o for o in coded if o["ok"] and o["roll_known"]]
        report[k] = {
            "tracked_rate": len(ok) / len(rows),
            "wrong": sum(o["tip_mm"] > a.wrong_mm for o in ok),
            "tip_error_mean_mm": float(np.mean(tips)) if tips else None,
            "coded_roll_known_rate": len(known) / max(len(coded), 1),
            "coded_rotation_mean_deg": float(np.mean([o["rot_deg"] for o in known])) if known else None,
            "time_ms_median": float(np.median([r[k]["ms"] for r in rows])),
            "tip_error_over_sigma": _honesty(ok),
            "lost": [{"pair": r["pair"], "sleeve": r["sleeve"], "roughness": round(r["roughness"], 3),
                      "tilt_deg": round(r["tilt_deg"], 1),
                      "reason": r[k]["reason"]} for r in rows if not r[k]["ok"]],
        }
    report["default"]["corner_errors"] = corner_summary([c for r in rows for c in r["default"].get("corners", [])])
    report["rows"] = rows  # per pair: the draw and each tracker's result
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except InputError as err:  # e.g. Mitsuba not installed: one line, not a traceback
        print(f"pbr_tracking: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None
