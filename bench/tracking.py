"""Stereo tracking benchmark: prints JSON.

Usage: python bench/tracking.py [DATASET_DIR] [--pairs N] [--seed S]
Without a folder it renders N pairs (default 20) at the default render noise into a temporary
folder. Per pair, measured in the same run:
- ours: MarkerTracker (detector in use: the paper's if installed, else the saddle fallback),
  cold (whole frame, state reset) and again on the same pair in ROI tracking;
- baseline_gftt: cv2.goodFeaturesToTrack + cv2.cornerSubPix in a box around the marker, each
  feature associated with the nearest visible true corner (oracle correspondence: favours the
  baseline) and fed to the same stereo pose solve;
- baseline_pnp: single-camera cv2.solvePnP (SOLVEPNP_SQPNP) on our left corners and indices.
Corner RMS [px] is against the true corners (detections within 2 px of a corner with
cos_view > 0), tip error [mm] against truth.json.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cvs.dataset import load_dataset  # noqa: E402
from cvs.marker_tracker import MarkerTracker  # noqa: E402
from rig.cli import main as cli_main  # noqa: E402
from solvers.homography_init import homography_pose  # noqa: E402


def _corner_errors(det: np.ndarray, truth: list) -> list[float]:
    vis = np.array([c.uv for c in truth if c.cos_view > 0])
    if det.size == 0 or vis.size == 0:
        return []
    d = np.linalg.norm(det[:, None] - vis[None], axis=2).min(axis=1)
    return d[d < 2.0].tolist()


def _summary(errs: list[float], tips: list[float], ok: int, n: int, times: list[float]) -> dict:
    e, t = np.array(errs), np.array(tips)
    return {
        "corner_rms_px": float(np.sqrt(np.mean(e**2))) if e.size else None,
        "corners_matched": int(e.size),
        "tip_error_mean_mm": float(t.mean()) if t.size else None,
        "tip_error_max_mm": float(t.max()) if t.size else None,
        "success_rate": ok / n,
        "time_ms_median": float(np.median(times)) if times else None,
    }


def _gftt(gray: np.ndarray, truth: list) -> tuple[np.ndarray, np.ndarray]:
    vis = [c for c in truth if c.cos_view > 0.2]
    uv = np.array([c.uv for c in vis])
    lo = np.maximum(uv.min(axis=0) - 30, 0).astype(int)
    hi = (uv.max(axis=0) + 30).astype(int)
    mask = np.zeros_like(gray)
    mask[lo[1] : hi[1], lo[0] : hi[0]] = 255
    pts = cv2.goodFeaturesToTrack(gray, 40, 0.05, 5, mask=mask)
    if pts is None:
        return np.zeros(0, int), np.zeros((0, 2))
    pts = cv2.cornerSubPix(gray, pts.astype(np.float32), (5, 5), (-1, -1), (3, 40, 1e-3)).reshape(-1, 2)
    idx, out = [], []
    for c in vis:
        d = np.linalg.norm(pts - c.uv, axis=1)
        j = int(d.argmin())
        if d[j] < 3.0:
            idx.append(c.index)
            out.append(pts[j])
    return np.array(idx, int), np.array(out, float).reshape(-1, 2)


def run(root: Path) -> dict:
    ds = load_dataset(root)
    cam, marker = ds.camera, ds.marker
    tracker = MarkerTracker(cam, marker)
    solver = tracker.solver
    res_ours: dict[str, list] = {"err": [], "tip": [], "cold": [], "roi": [], "tip_roi": []}
    ok = ok_roi = ok_g = ok_p = 0
    stages: dict[str, list[float]] = {}
    g_err: list[float] = []
    g_tip: list[float] = []
    g_time: list[float] = []
    p_tip: list[float] = []
    p_time: list[float] = []
    for (lp, rp), t in zip(ds.pairs, ds.truth):
        L, R = cv2.imread(str(lp)), cv2.imread(str(rp))
        tracker.reset()
        r = tracker.track(L, R)
        res_ours["cold"].append(r.time_ms)
        res_ours["err"] += _corner_errors(r.corners_left, t.corners_left)
        res_ours["err"] += _corner_errors(r.corners_right, t.corners_right)
        if r.ok and r.tip_left is not None:
            ok += 1
            res_ours["tip"].append(1e3 * float(np.linalg.norm(r.tip_left - t.tip)))
        r2 = tracker.track(L, R)  # ROI tracking on the same pair
        res_ours["roi"].append(r2.time_ms)
        for k, v in r2.timings.items():
            stages.setdefault(k, []).append(v)
        if r2.ok and r2.tip_left is not None:
            ok_roi += 1
            res_ours["tip_roi"].append(1e3 * float(np.linalg.norm(r2.tip_left - t.tip)))
        # baseline (a): gFTT + cornerSubPix, oracle correspondence, same stereo solve
        gl, gr = cv2.cvtColor(L, cv2.COLOR_BGR2GRAY), cv2.cvtColor(R, cv2.COLOR_BGR2GRAY)
        t0 = time.perf_counter()
        il, ul = _gftt(gl, list(t.corners_left))
        ir, ur = _gftt(gr, list(t.corners_right))
        g_err += _corner_errors(ul, t.corners_left) + _corner_errors(ur, t.corners_right)
        if il.size >= 4 and ir.size >= 1:
            T0 = homography_pose(cam.left, marker.corners()[il], ul)
            best = None
            for start in (T0, r.T_left_marker if r.T_left_marker is not None else T0):
                p = solver.solve(il, ul, ir, ur, start)
                if best is None or p.rms_px < best.rms_px:
                    best = p
            g_time.append(1e3 * (time.perf_counter() - t0))
            if best is not None and best.rms_px <= tracker.settings.max_rms_px:
                ok_g += 1
                g_tip.append(1e3 * float(np.linalg.norm(best.tip_left - t.tip)))
        # baseline (b): left camera only, SQPnP on our corners and indices
        if r.ok and r.match is not None:
            keep = r.match.index_left >= 0
            idx, uv = r.match.index_left[keep], r.corners_left[keep]
            if idx.size >= 3:
                t0 = time.perf_counter()
                okp, rv, tv = cv2.solvePnP(
                    solver.marker_points(idx), uv, cam.left.K, cam.left.dist, flags=cv2.SOLVEPNP_SQPNP
                )
                p_time.append(1e3 * (time.perf_counter() - t0))
                if okp:
                    Rm = cv2.Rodrigues(rv)[0]
                    T = np.eye(4)
                    T[:3, :3], T[:3, 3] = Rm, tv.reshape(3)
                    T = solver.orient(T)
                    tip = T[:3, :3] @ marker.tip() + T[:3, 3]
                    ok_p += 1
                    p_tip.append(1e3 * float(np.linalg.norm(tip - t.tip)))
    n = len(ds.pairs)
    ours = _summary(res_ours["err"], res_ours["tip"], ok, n, res_ours["cold"])
    ours["time_ms_cold_median"] = ours.pop("time_ms_median")
    ours["time_ms_roi_median"] = float(np.median(res_ours["roi"]))
    ours["tip_error_mean_mm_roi"] = float(np.mean(res_ours["tip_roi"])) if res_ours["tip_roi"] else None
    ours["success_rate_roi"] = ok_roi / n
    ours["roi_stage_ms_median"] = {k: float(np.median(v)) for k, v in stages.items()}
    det = type(tracker.detector_left).__module__
    return {
        "dataset": str(root),
        "pairs": n,
        "detector": det,
        "ours": ours,
        "baseline_gftt_oracle_same_solve": _summary(g_err, g_tip, ok_g, n, g_time),
        "baseline_pnp_sqpnp_left_only": _summary([], p_tip, ok_p, n, p_time),
        "targets": {"corner_rms_px": 0.08, "tip_error_mean_mm": 0.1, "time_ms_roi": 5.0, "time_ms_cold": 60.0},
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", nargs="?", help="dataset folder (default: render one)")
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    if a.dataset:
        print(json.dumps(run(Path(a.dataset)), indent=1))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "ds"
        with contextlib.redirect_stdout(sys.stderr):  # keep stdout pure JSON
            rc = cli_main(["render", "--out", str(root), "--pairs", str(a.pairs), "--seed", str(a.seed)])
        if rc:
            return rc
        print(json.dumps(run(root), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
