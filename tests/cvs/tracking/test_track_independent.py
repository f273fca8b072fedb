"""`wristmark track` on stereo sets it has never seen, from the independent renderer.

wristmark_testing/independent_render.py (numpy / opencv only, written from docs/design.md) draws its own
stereo endoscope (fx 1200-1500 px, 4-6 mm baseline, k1 in [-0.3, -0.15] with k2, p1, p2, a small rotation between the
eyes), ray-casts the marker sleeve on a plain tube before a textured tissue plane and adds optics blur,
gamma and shot + read noise. The tracker (subprocess, `--json`) must find the marker in nearly every pair
with a tip error (vs truth.json, both in the left camera frame) well under 0.2 mm.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from wristmark_testing import independent_dataset_check as chk
from wristmark_testing import independent_render as ind

ROOT = Path(__file__).resolve().parents[3]
WRISTMARK = ROOT / ".venv" / "bin" / "wristmark"
if not WRISTMARK.exists():  # pragma: no cover - other installs
    WRISTMARK = Path(sys.executable).with_name("wristmark")


def test_renderer_rays_invert_the_projection() -> None:
    """Rays cast from cv2.projectPoints pixels pass through the 3D point (both eyes, frames of docs/design.md),
    and the ray through a true corner hits the sleeve at that corner."""
    rng = np.random.default_rng(1)
    rig = ind.random_rig(rng)
    X = np.column_stack([rng.uniform(-0.03, 0.03, 50), rng.uniform(-0.02, 0.02, 50), rng.uniform(0.05, 0.12, 50)])
    for eye in (rig.left, rig.right):
        d = ind.rays(eye, ind.project(eye, X))
        v = X - eye.centre
        miss = np.linalg.norm(v - np.sum(v * d, axis=1, keepdims=True) * d, axis=1)
        assert miss.max() < 1e-9
    marker, look = ind.Marker(), ind.Look()
    Rm, t = ind.random_pose(rng, rig, marker, look)
    Xc = t + marker.corners() @ Rm.T
    for eye in (rig.left, rig.right):
        facing = ind.cos_view(eye, Xc, (marker.corners() / marker.radius) @ Rm.T) > 0.2
        lab, Xh, _, _ = ind.trace(ind.rays(eye, ind.project(eye, Xc[facing])), eye.centre, Rm, t, marker, look)
        assert np.all(lab >= ind.SLEEVE0) and np.abs(Xh - Xc[facing]).max() < 1e-9


def _check_tracking(folder: Path, tip_tol_m: float, min_success: float) -> dict:
    results, _ = chk.run_track(folder, WRISTMARK)
    score = chk.score_track(folder, results)
    assert len(results) == score["pairs"]
    assert score["success_rate"] >= min_success, score["failures"]
    bad = [(r["pair"], r["tip_err_m"]) for r in score["rows"] if r["ok"] and r["tip_err_m"] > tip_tol_m]
    assert not bad, f"tip errors above {tip_tol_m * 1e3} mm (pair, m): {bad}; dataset {folder}"
    return score


@pytest.mark.slow
def test_track_independent_1080p(tmp_path: Path) -> None:
    """3 full-size pairs, reference marker: every pair ok, tip error < 0.2 mm each, < 0.1 mm on average."""
    out = tmp_path / "ind"
    ind.render_dataset(out, pairs=3, seed=21)
    s = _check_tracking(out, 0.2e-3, 1.0)
    assert s["tip_err_mean_mm"] < 0.1
    assert s["corner_err_rms_px"] < 0.3 and s["corners_unmatched"] == 0


@pytest.mark.slow
def test_track_independent_other_marker(tmp_path: Path) -> None:
    """2 pairs (1440x810) with a 14-column sleeve of radius 4 mm (marker.yaml of docs/design.md), JPEG 90."""
    out = tmp_path / "ind14"
    ind.render_dataset(out, pairs=2, seed=22, scale=0.75, marker=ind.Marker(radius=0.004, columns=14),
                       look=ind.Look(jpeg=90))
    _check_tracking(out, 0.2e-3, 1.0)


@pytest.mark.slow
def test_track_independent_tip_pointing_left(tmp_path: Path) -> None:
    """The sleeve is symmetric under a half turn about x_wm: with the tip pointing LEFT (our own
    scenes always point right) the direction of z_wm must come from the image (cvs.tracking.axis),
    else the tip is off by 2 x tip_offset = 30 mm."""
    out = tmp_path / "left"
    ind.render_dataset(out, pairs=2, seed=23, scale=0.5, look=ind.Look(direction="left"))
    _check_tracking(out, 0.3e-3, 1.0)


def test_score_matches_corners_to_truth(tmp_path: Path) -> None:
    """score_track on a fake tracker output built from truth: zero errors; a reversed axis is 2 x offset."""
    out = tmp_path / "fake"
    ind.render_dataset(out, pairs=1, seed=24, scale=0.25)
    truth = __import__("json").loads((out / "truth.json").read_text())[0]
    good = {"ok": True, "tip": truth["tip"], "R": truth["R"], "t": truth["t"], "rms_px": 0.0, "time_ms": 1.0,
            "corners_left": [c["uv"] for c in truth["corners_left"] if c["cos_view"] > 0.2],
            "corners_right": [c["uv"] for c in truth["corners_right"] if c["cos_view"] > 0.2]}
    s = chk.score_track(out, [good])
    assert s["success_rate"] == 1 and s["tip_err_max_mm"] < 1e-9 and s["corner_err_max_px"] < 1e-9
    R = np.asarray(truth["R"])
    flipped = dict(good, tip=(np.asarray(truth["t"]) - R[:, 2] * 0.015).tolist())
    assert math.isclose(chk.score_track(out, [flipped])["tip_err_max_mm"], 30.0, rel_tol=1e-6)
    assert chk.score_track(out, [{"ok": False, "reason": "x"}])["failures"] == [{"pair": 0, "reason": "x"}]
