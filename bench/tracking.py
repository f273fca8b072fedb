"""Stereo tracking benchmark: prints JSON.

Usage: python bench/tracking.py [DATASET_DIR] [--pairs N] [--seed S] [--detectors paper,saddle]
Without a folder it renders N pairs (default 20) at the default render noise into a temporary
folder. Per pair, measured in the same run:
- ours: MarkerTracker once per corner detector, side by side ("paper": cvs.corners.detector,
  the paper's Sec. III.A; "saddle": the cvs.corners.saddle fallback), cold (whole frame, state
  reset) and again on the same pair in ROI tracking; times per stereo pair (total and the
  detection stage);
- detector_only: the paper's detector alone per image, cold (whole frame) and in ROI tracking,
  with the corner RMS of its final (HTM-refined) corners and of the paper's eq. 10 quadric, and
  the ROI time per stage (crop + grey conversion, smoothing + CL + NMS, X-corner tests + chain,
  sub-pixel fits; the rest is Python glue);
- baseline_gftt: cv2.goodFeaturesToTrack + cv2.cornerSubPix in a box around the marker, each
  feature associated with the nearest visible true corner (oracle correspondence: favours the
  baseline) and fed to the same stereo pose solve;
- baseline_pnp: single-camera cv2.solvePnP (SOLVEPNP_SQPNP) on our left corners and indices
  (those of the first detector listed).
Corner RMS [px] is against the true corners (detections within 2 px of a corner with
cos_view > 0), tip error [mm] against truth.json.
- coded: the same poses rendered with the coded sleeve (``--coded``, default
  configs/marker_coded.yaml; docs/design.md "The coded marker"), tracked by the first detector
  listed, side by side with the reference sleeve ("reference": that detector's tracker on the
  reference pairs, measured again in the same loop): success rate, roll_known rate, roll error
  [deg] (rotation about z_wm of R_true^T R), rotation error [deg] (the whole rotation, roll
  included; the reference sleeve's only modulo its symmetries, so not given), tip error [mm],
  cold and ROI time per pair and the time the code reading adds per pair [ms] (median).
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

from wristmark.cli.main import main as cli_main  # noqa: E402
from wristmark.cvs.corners.detector import MarkerCornerDetector  # noqa: E402
from wristmark.cvs.tracking.homography_init import homography_pose  # noqa: E402
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.models.config_files import CONFIG_DIR
from wristmark.sim.dataset import StereoDataset, load_dataset  # noqa: E402


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


def _ours(ds: StereoDataset, detector: str) -> tuple[dict, list]:
    """The tracker with one detector over the dataset: summary and the cold results per pair."""
    tracker = MarkerTracker(ds.camera, ds.marker, TrackerSettings(detector=detector))
    err: list[float] = []
    tip: list[float] = []
    tip_roi: list[float] = []
    cold: list[float] = []
    roi: list[float] = []
    det_cold: list[float] = []
    det_roi: list[float] = []
    stages: dict[str, list[float]] = {}
    ok = ok_roi = 0
    results = []
    for (lp, rp), t in zip(ds.pairs, ds.truth):
        L, R = cv2.imread(str(lp)), cv2.imread(str(rp))
        tracker.reset()
        r = tracker.track(L, R)
        results.append(r)
        cold.append(r.time_ms)
        det_cold.append(r.timings["detect"])
        err += _corner_errors(r.corners_left, t.corners_left) + _corner_errors(r.corners_right, t.corners_right)
        if r.ok and r.tip_left is not None:
            ok += 1
            tip.append(1e3 * float(np.linalg.norm(r.tip_left - t.tip)))
        r2 = tracker.track(L, R)  # ROI tracking on the same pair
        roi.append(r2.time_ms)
        det_roi.append(r2.timings["detect"])
        for k, v in r2.timings.items():
            stages.setdefault(k, []).append(v)
        if r2.ok and r2.tip_left is not None:
            ok_roi += 1
            tip_roi.append(1e3 * float(np.linalg.norm(r2.tip_left - t.tip)))
    n = len(ds.pairs)
    out = _summary(err, tip, ok, n, cold)
    out["time_ms_cold_median"] = out.pop("time_ms_median")
    out["time_ms_roi_median"] = float(np.median(roi))
    out["detect_ms_cold_median"] = float(np.median(det_cold))
    out["detect_ms_roi_median"] = float(np.median(det_roi))
    out["tip_error_mean_mm_roi"] = float(np.mean(tip_roi)) if tip_roi else None
    out["success_rate_roi"] = ok_roi / n
    out["roi_stage_ms_median"] = {k: float(np.median(v)) for k, v in stages.items()}
    out["detector_class"] = type(tracker.detector_left).__module__ + "." + type(tracker.detector_left).__name__
    return out, results


def _detector_only(ds: StereoDataset) -> dict:
    """The paper's detector alone, per image: cold and ROI time, RMS of final and eq. 10 corners."""
    det = MarkerCornerDetector()
    cold: list[float] = []
    roi: list[float] = []
    roi_stages: dict[str, list[float]] = {}
    err: list[float] = []
    err_q: list[float] = []
    found = roi_used = 0
    for (lp, rp), t in zip(ds.pairs, ds.truth):
        for path, truth in ((lp, t.corners_left), (rp, t.corners_right)):
            g = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
            det.reset()
            t0 = time.perf_counter()
            c = det.track(g)
            cold.append(1e3 * (time.perf_counter() - t0))
            t0 = time.perf_counter()
            c2 = det.track(g)
            roi.append(1e3 * (time.perf_counter() - t0))
            roi_used += int(c2.roi is not None)
            for k, v in c2.extras.items():
                roi_stages.setdefault(k, []).append(v)
            found += int(c.corners.shape[0] >= 3)
            vis = np.array([x.uv for x in truth if x.cos_view > 0])
            if c.corners.shape[0] and vis.size:
                d = np.linalg.norm(c.corners[:, None] - vis[None], axis=2)
                j = d.argmin(axis=1)
                keep = d[np.arange(j.size), j] < 2.0
                err += d[np.arange(j.size), j][keep].tolist()
                err_q += np.linalg.norm(c.corners_quadric[keep] - vis[j[keep]], axis=1).tolist()
    e, q = np.array(err), np.array(err_q)
    return {
        "images": 2 * len(ds.pairs),
        "chain_found_rate": found / (2 * len(ds.pairs)),
        "roi_used_rate": roi_used / (2 * len(ds.pairs)),
        "corner_rms_px": float(np.sqrt(np.mean(e**2))) if e.size else None,
        "corner_rms_px_eq10_quadric": float(np.sqrt(np.mean(q**2))) if q.size else None,
        "corners_matched": int(e.size),
        "time_ms_per_image_cold_median": float(np.median(cold)),
        "time_ms_per_image_cold_max": float(np.max(cold)),
        "time_ms_per_image_roi_median": float(np.median(roi)),
        "time_ms_per_image_roi_max": float(np.max(roi)),
        "roi_stage_ms_median": {k: float(np.median(v)) for k, v in roi_stages.items()},
        "image_size": list(ds.camera.image_size),
    }


def _rotation_errors_deg(R_est: np.ndarray, R_true: np.ndarray) -> tuple[float, float]:
    """(whole rotation angle, roll about z_wm) of R_true^T R_est [deg]."""
    E = R_true.T @ R_est
    whole = float(np.degrees(np.arccos(np.clip((np.trace(E) - 1.0) / 2.0, -1.0, 1.0))))
    return whole, float(np.degrees(abs(np.arctan2(E[1, 0] - E[0, 1], E[0, 0] + E[1, 1]))))


def _sleeve(ds: StereoDataset, detector: str) -> dict:
    """One sleeve's tracking (cold, then ROI on the same pair): success, roll and rotation errors
    when the roll is known, tip error, times and the code reading's time."""
    tracker = MarkerTracker(ds.camera, ds.marker, TrackerSettings(detector=detector))
    ok = known = 0
    tip: list[float] = []
    roll: list[float] = []
    rot: list[float] = []
    cold: list[float] = []
    roi: list[float] = []
    code: list[float] = []
    for (lp, rp), t in zip(ds.pairs, ds.truth):
        L, R = cv2.imread(str(lp)), cv2.imread(str(rp))
        tracker.reset()
        r = tracker.track(L, R)
        cold.append(r.time_ms)
        r2 = tracker.track(L, R)
        roi.append(r2.time_ms)
        for x in (r, r2):
            if "code" in x.timings:
                code.append(x.timings["code"])
        if not (r.ok and r.tip_left is not None and r.T_left_marker is not None):
            continue
        ok += 1
        tip.append(1e3 * float(np.linalg.norm(r.tip_left - t.tip)))
        if r.roll_known:
            known += 1
            whole, about_z = _rotation_errors_deg(r.T_left_marker[:3, :3], np.asarray(t.R, float))
            rot.append(whole)
            roll.append(about_z)
    n = len(ds.pairs)

    def stats(v: list[float]) -> dict:
        return {"mean": float(np.mean(v)), "max": float(np.max(v))} if v else {"mean": None, "max": None}

    return {
        "success_rate": ok / n,
        "roll_known_rate": known / n,
        "roll_error_deg": stats(roll),
        "rotation_error_deg": stats(rot),
        "tip_error_mm": stats(tip),
        "time_ms_cold_median": float(np.median(cold)),
        "time_ms_roi_median": float(np.median(roi)),
        "code_ms_median": float(np.median(code)) if code else None,
    }


def run_coded(reference: Path, coded: Path, detector: str) -> dict:
    """The coded sleeve beside the reference sleeve on the same poses, in one loop."""
    ds_ref, ds_code = load_dataset(reference), load_dataset(coded)
    return {"reference": _sleeve(ds_ref, detector), "coded": _sleeve(ds_code, detector),
            "targets": {"code_ms": 0.3, "roll_error_mean_deg": 0.5}}


def run(root: Path, detectors: tuple[str, ...] = ("paper", "saddle")) -> dict:
    ds = load_dataset(root)
    cam, marker = ds.camera, ds.marker
    ours: dict[str, dict] = {}
    first: list = []
    for name in detectors:
        ours[name], res = _ours(ds, name)
        first = first or res
    solver = MarkerTracker(cam, marker, TrackerSettings(detector=detectors[0])).solver
    max_rms = TrackerSettings().max_rms_px
    ok_g = ok_p = 0
    g_err: list[float] = []
    g_tip: list[float] = []
    g_time: list[float] = []
    p_tip: list[float] = []
    p_time: list[float] = []
    for (lp, rp), t, r in zip(ds.pairs, ds.truth, first):
        L, R = cv2.imread(str(lp)), cv2.imread(str(rp))
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
            if best is not None and best.rms_px <= max_rms:
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
    out = {
        "dataset": str(root),
        "pairs": n,
        "ours": ours,
        "baseline_gftt_oracle_same_solve": _summary(g_err, g_tip, ok_g, n, g_time),
        "baseline_pnp_sqpnp_left_only": _summary([], p_tip, ok_p, n, p_time),
        "targets": {"corner_rms_px": 0.08, "tip_error_mean_mm": 0.1, "time_ms_roi": 5.0, "time_ms_cold": 60.0},
    }
    if "paper" in detectors:
        out["detector_only_paper"] = _detector_only(ds)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", nargs="?", help="dataset folder (default: render one)")
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--detectors", default="paper,saddle", help="comma-separated: paper, saddle, auto")
    ap.add_argument("--coded", default=str(CONFIG_DIR / "marker_coded.yaml"),
                    help="coded marker file rendered at the same poses ('' to skip)")
    a = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    dets = tuple(d.strip() for d in a.detectors.split(",") if d.strip())
    if a.dataset:
        print(json.dumps(run(Path(a.dataset), dets), indent=1))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "ds"
        with contextlib.redirect_stdout(sys.stderr):  # keep stdout pure JSON
            rc = cli_main(["render", "--out", str(root), "--pairs", str(a.pairs), "--seed", str(a.seed)])
            if not rc and a.coded:
                rc = cli_main(["render", "--out", str(Path(tmp) / "coded"), "--pairs", str(a.pairs), "--seed",
                               str(a.seed), "--marker", a.coded])
        if rc:
            return rc
        out = run(root, dets)
        if a.coded:
            out["coded_sleeve"] = run_coded(root, Path(tmp) / "coded", dets[0])
        print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
