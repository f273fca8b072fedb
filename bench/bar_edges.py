"""How far the print's bar edges are found from where they are, on path-traced pairs: the bar
measurement's largest gradient against an erf edge fit.

The tracker's bars (cvs.tracking.print_edges.measure_edges) take the largest dark-to-white step of
each printed edge's profile, and keep it only where the profile rises by a quarter of its span per
pixel: a blurred edge (a sleeve close to the lens, out of focus) rises slower and is refused, and
a half-clipped one is found off its place (path-traced 1515/15, docs/notes/highlight-stripe.md).
(The tracker now measures the edges those tests refuse by such a fit, measure_edges'
``blur_fit_px``, its sigma bounded by ``blur_fit_max_sigma_px``; here "kept" is the gradient's
tests alone, and "tracker_fit" the tracker's own fit of the refused edges, by the smallest of the
bounds SIGMA_BOUNDS_PX under which it keeps them.) This bench asks, at each pair's
*true* pose, every printed edge sample that faces the camera (as
the tracker does): where does the largest gradient put it, where does a fitted blurred step
(a + b Phi((t - t0) / sigma) on the profile's unclipped samples) put it, and which of them the
tracker's tests keep. Offsets are along the edge's image normal [px] from the true projection.

    python bench/bar_edges.py --cache runs/pbr/s1515 --pairs 60
    python bench/bar_edges.py --pbr-data coded_two_corners

The pairs are those `bench/pbr_tracking.py --cache DIR` keeps (pair_<i>.npz: even i a reference
sleeve, odd i a coded one, as it draws them) or a committed pair of tests/data/pbr (by its name:
coded_* or reference_*). One JSON object on stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.special import erf

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.gray_image import to_gray
from wristmark.cvs.tracking.print_edges import measure_edges, printed_edges
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

PBR_DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "pbr"
HALF_SPAN_PX = 7.5  # the profile fitted: +-this along the edge's normal [px]
CLIPPED = 250  # grey level the tracker counts as clipped (TrackerSettings.clipped_level)
SIGMA_BOUNDS_PX = (1.5, 2.5, 6.0)  # bounds on the tracker fit's sigma (6: the fit's own bound)


def _profile(grey: np.ndarray, uv: np.ndarray, u: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Bilinear grey levels at uv + t u for every t in ``ts`` [px]."""
    xy = uv[None] + ts[:, None] * u[None]
    m = cv2.remap(grey, xy[:, 0].astype(np.float32)[None], xy[:, 1].astype(np.float32)[None], cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE)
    return np.asarray(m[0], float)


def _erf_edge(ts: np.ndarray, prof: np.ndarray, start: float) -> tuple[float, float] | None:
    """The edge (offset t0 [px], blur sigma [px]) of a blurred step fitted to the unclipped samples
    of ``prof``; None where too few are unclipped or the fit leaves its bounds."""
    ok = prof < CLIPPED
    if ok.sum() < 8 or float(np.ptp(prof[ok])) < 12.0:
        return None
    t, p = ts[ok], prof[ok]

    def residual(x: np.ndarray) -> np.ndarray:
        return x[0] + x[1] * 0.5 * (1.0 + erf((t - x[2]) / (math.sqrt(2.0) * x[3]))) - p

    x0 = np.array([p.min(), max(float(np.ptp(p)), 12.0), start, 1.5])
    try:
        r = least_squares(residual, x0, bounds=([-64.0, 6.0, -6.0, 0.3], [320.0, 640.0, 6.0, 6.0]))
    except ValueError:
        return None
    if not r.success or abs(r.x[2]) >= 6.0 - 1e-3:
        return None
    return float(r.x[2]), float(r.x[3])


def edge_offsets(views: tuple[np.ndarray, np.ndarray], camera: Any, marker: MarkerModel, T: np.ndarray,
                 min_facing: float = 0.5) -> dict[str, list[float]]:
    """Per edge sample facing the camera at the true pose ``T`` ({wm} in {ll}): the largest
    gradient's offset (refined as the tracker does), whether the tracker keeps it, and the erf
    fit's offset and sigma [px]; and for a sample the gradient refuses and the tracker's own fit
    keeps, its offset and the smallest of SIGMA_BOUNDS_PX under which it keeps it (NaN: not kept)."""
    edges = printed_edges(marker)
    out: dict[str, list[float]] = {"gradient": [], "kept": [], "erf": [], "sigma": [], "fit": [], "fit_bound": []}
    R, t = T[:3, :3], T[:3, 3]
    for side, grey in enumerate(views):
        right = side == 1
        # the largest gradient's tests alone (no blurred-step fit)
        kept = measure_edges(grey, camera, right, T, edges, min_facing=min_facing, blur_fit_px=0.0)
        kept_at = {int(k): i for i, k in enumerate(kept.index)}
        # the tracker's fit of the refused samples, under each bound on its sigma
        fitted = [measure_edges(grey, camera, right, T, edges, min_facing=min_facing, blur_fit_max_sigma_px=b)
                  for b in SIGMA_BOUNDS_PX]
        fitted_at = [{int(k): i for i, k in enumerate(f.index)} for f in fitted]
        P = edges.points @ R.T + t
        n = edges.normals @ R.T
        centre = -camera.R.T @ np.asarray(camera.T, float).reshape(3) if right else np.zeros(3)
        sight = centre - P
        facing = np.einsum("ij,ij->i", n, sight) / np.linalg.norm(sight, axis=1)
        sel = np.flatnonzero((facing >= min_facing) & (facing[edges.partner] >= min_facing))
        if sel.size == 0:
            continue
        project = camera.project_right if right else camera.project_left
        both = np.asarray(project(np.vstack([P[sel], P[sel] + 1e-5 * (edges.across[sel] @ R.T)])), float)
        uv, d = both[:sel.size], both[sel.size:] - both[:sel.size]
        u = d / np.linalg.norm(d, axis=1)[:, None]
        h, w = grey.shape
        g32 = grey.astype(np.float32)
        ts = np.arange(-HALF_SPAN_PX, HALF_SPAN_PX + 1e-9, 0.5)
        inner = np.abs(ts) <= 4.0  # the tracker's search (3.5 px) and the half-px margin
        for k, e in enumerate(sel):
            lo = HALF_SPAN_PX + 2
            if not (lo < uv[k, 0] < w - lo and lo < uv[k, 1] < h - lo):
                continue
            prof = _profile(g32, uv[k], u[k], ts)
            pin = prof[inner]
            g = 0.5 * (pin[2:] - pin[:-2])
            j = int(np.argmax(g))
            grad = float(ts[inner][j + 1])
            if int(e) in kept_at:  # the tracker's own refined offset
                grad = float(np.dot(kept.uv[kept_at[int(e)]] - uv[k], u[k]))
            fit = _erf_edge(ts, prof, grad)
            out["gradient"].append(grad)
            out["kept"].append(float(int(e) in kept_at))
            out["erf"].append(float("nan") if fit is None else fit[0])
            out["sigma"].append(float("nan") if fit is None else fit[1])
            within = [j for j in range(len(SIGMA_BOUNDS_PX)) if int(e) in fitted_at[j]] if int(e) not in kept_at else []
            if within:
                f, j = fitted[within[0]], fitted_at[within[0]][int(e)]
                out["fit"].append(float(np.dot(f.uv[j] - uv[k], u[k])))
                out["fit_bound"].append(SIGMA_BOUNDS_PX[within[0]])
            else:
                out["fit"].append(float("nan"))
                out["fit_bound"].append(float("nan"))
    return out


def _stats(x: np.ndarray) -> dict[str, Any]:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"n": 0}
    return {"n": int(x.size), "rms_px": round(float(np.sqrt(np.mean(x ** 2))), 3),
            "median_abs_px": round(float(np.median(np.abs(x))), 3)}


def summary(offsets: dict[str, list[float]]) -> dict[str, Any]:
    """The offsets' RMS and median |.| [px]: the tracker's kept samples (its gradient, the erf fit
    on the same samples) and the refused ones (their gradient and erf fit); and the refused ones
    the tracker's fit keeps, by the bound on its sigma ("sigma <= 1.5": kept under 1.5 px, ...,
    each bin the samples the next smaller bound refuses), with their mean offset."""
    g, k, e, s, f, fb = (np.asarray(offsets[key], float)
                         for key in ("gradient", "kept", "erf", "sigma", "fit", "fit_bound"))
    kept, refused = k > 0.5, k <= 0.5
    by_bound = {}
    for b in SIGMA_BOUNDS_PX:
        x = f[fb == b]
        by_bound[f"sigma <= {b}"] = {**_stats(x), **({"mean_px": round(float(x.mean()), 3)} if x.size else {})}
    return {"samples": int(g.size), "kept": {"gradient": _stats(g[kept]), "erf": _stats(e[kept])},
            "refused": {"gradient": _stats(g[refused]), "erf": _stats(e[refused])},
            "erf_sigma_median_px": None if not np.isfinite(s).any() else round(float(np.nanmedian(s)), 2),
            "tracker_fit": by_bound}


def _pairs(a: argparse.Namespace) -> list[tuple[str, tuple[np.ndarray, np.ndarray], MarkerModel, np.ndarray]]:
    coded, reference = MarkerModel.load(default_config("marker_coded.yaml")), MarkerModel()
    out = []
    if a.pbr_data:
        for name in a.pbr_data.split(","):
            folder = PBR_DATA / name
            truth_file = folder / "truth.json"
            if not truth_file.is_file():
                raise InputError(f"no committed path-traced pair {name!r} ({truth_file} missing)")
            truth = json.loads(truth_file.read_text())
            views = tuple(cv2.imread(str(folder / f"pair_00_{v}.png"), cv2.IMREAD_GRAYSCALE) for v in ("left", "right"))
            if any(v is None for v in views):
                raise InputError(f"{folder}: pair_00_left.png / pair_00_right.png missing or unreadable")
            out.append((name, views, coded if name.startswith("coded") else reference,
                        np.asarray(truth["T_left_marker"], float)))
    if a.cache:
        for i in range(a.pairs):
            f = Path(a.cache) / f"pair_{i}.npz"
            if not f.is_file():
                continue
            z = np.load(f)
            out.append((f"{Path(a.cache).name}/{i}", (to_gray(z["left"]), to_gray(z["right"])),
                        coded if i % 2 else reference, np.asarray(z["T_left_marker"], float)))
    if not out:
        raise InputError("no pairs: give --cache DIR (pair_<i>.npz of bench/pbr_tracking.py) or --pbr-data NAME")
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cache", help="pairs of `bench/pbr_tracking.py --cache DIR`")
    p.add_argument("--pairs", type=int, default=60, help="the first N pairs of --cache")
    p.add_argument("--pbr-data", default="", help="committed pairs of tests/data/pbr, by name (comma-separated)")
    p.add_argument("--min-facing", type=float, default=0.5, help="as the tracker's bars (measure_edges)")
    a = p.parse_args()
    try:
        pairs = _pairs(a)
    except InputError as e:
        print(f"bar_edges: {e}", file=sys.stderr)
        return 2
    camera = load_calibration(str(default_config("camera.yaml")))
    rows, pooled = [], {"gradient": [], "kept": [], "erf": [], "sigma": [], "fit": [], "fit_bound": []}
    for name, views, marker, T in pairs:
        off = edge_offsets(views, camera, marker, T, a.min_facing)
        for key in pooled:
            pooled[key] += off[key]
        rows.append({"pair": name, **summary(off)})
    print(json.dumps({"pairs": len(rows), "min_facing": a.min_facing, "pooled": summary(pooled), "rows": rows},
                     indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
