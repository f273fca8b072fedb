"""`wristmark render` output checked against docs/design.md's dataset contract by an independent checker.

The checker (wristmark_testing/independent_dataset_check.py) uses only numpy / opencv / yaml / json. Here it runs on
a small set written by the CLI (subprocess), on corrupted copies (it must catch each corruption) and on a
set from the independent renderer (wristmark_testing/independent_render.py), which must obey the same contract.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from wristmark_testing import independent_dataset_check as chk
from wristmark_testing import independent_render as ind

pytestmark = [pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
WRISTMARK = ROOT / ".venv" / "bin" / "wristmark"
if not WRISTMARK.exists():  # pragma: no cover - other installs
    WRISTMARK = Path(sys.executable).with_name("wristmark")


@pytest.fixture(scope="module")
def ours(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """3 pairs from `wristmark render` at half size (960x540)."""
    out = tmp_path_factory.mktemp("contract") / "ds"
    proc = subprocess.run([str(WRISTMARK), "render", "--out", str(out), "--pairs", "3", "--seed", "7",
                           "--scale", "0.5"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def summary(ours: Path) -> dict[str, Any]:
    """Checker summary of the `wristmark render` set."""
    return chk.check_dataset(ours)


def test_files_and_no_violation(ours: Path, summary: dict[str, Any]) -> None:
    names = {p.name for p in ours.iterdir()}
    expected = {"calib.yaml", "marker.yaml", "truth.json"} | {f"pair_{i:02d}_{s}.png" for i in range(3)
                                                               for s in ("left", "right")}
    assert expected <= names
    assert summary["violations"] == [] and summary["ok"]
    assert summary["pairs"] == 3 and summary["image_size"] == [960, 540]


def test_truth_is_the_posed_marker(summary: dict[str, Any]) -> None:
    """uv = cv2.projectPoints of the posed corners, cos_view recomputed, tip = t + R [0, 0, tip_offset]."""
    assert summary["proj_err_max_px"] < 1e-6
    assert summary["cos_err_max"] < 1e-9
    assert summary["tip_err_max_m"] < 1e-9
    assert 4 <= summary["visible_corners_min"] <= summary["visible_corners_max"] <= 8


def test_pixels_agree_with_truth(summary: dict[str, Any]) -> None:
    """cornerSubPix from 1-1.5 px away (loose: biased on the curved, shaded marker) and the fit of the ideal
    pattern (tight: catches a half- or quarter-pixel convention error)."""
    sp, mf = summary["subpix"], summary["model_fit"]
    assert sp["n"] >= 6 and sp["rms_px"] < chk.SUBPIX_RMS_TOL_PX and sp["max_px"] < chk.SUBPIX_MAX_TOL_PX
    assert mf["n"] >= 6 and mf["rms_px"] < chk.MODEL_RMS_TOL_PX and mf["max_px"] < chk.MODEL_MAX_TOL_PX
    assert math.hypot(*mf["bias_px"]) < chk.MODEL_BIAS_TOL_PX


def test_patch_colours_follow_the_pattern(summary: dict[str, Any]) -> None:
    assert summary["patches"]["pairs_compared"] >= 20 and summary["patches"]["wrong"] == 0


def test_command_line(ours: Path, tmp_path: Path) -> None:
    script = Path(chk.__file__)
    ok = subprocess.run([sys.executable, str(script), str(ours)], capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stdout[-2000:]
    assert json.loads(ok.stdout)["ok"] is True
    bad = tmp_path / "bad"
    shutil.copytree(ours, bad)
    (bad / "pair_01_right.png").unlink()
    res = subprocess.run([sys.executable, str(script), str(bad)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 1 and json.loads(res.stdout)["ok"] is False


def _copy(ours: Path, tmp_path: Path) -> tuple[Path, list[dict[str, Any]]]:
    bad = tmp_path / "bad"
    shutil.copytree(ours, bad)
    return bad, json.loads((bad / "truth.json").read_text())


def test_catches_wrong_truth(ours: Path, tmp_path: Path) -> None:
    bad, truth = _copy(ours, tmp_path)
    truth[1]["corners_left"][3]["uv"][0] += 1e-3
    truth[2]["tip"][2] += 1e-4
    truth[0]["corners_right"][5]["cos_view"] *= 0.9
    truth[0]["corners_right"][2]["index"] = 7
    (bad / "truth.json").write_text(json.dumps(truth))
    v = " ".join(chk.check_dataset(bad, model_fit=False)["violations"])
    assert "truth[1].corners_left: uv differ" in v and "truth[2]: tip differs" in v
    assert "truth[0].corners_right: indices" in v


def test_catches_shifted_image(ours: Path, tmp_path: Path) -> None:
    """A one-pixel shift of every image (a pixel-convention or frame error) must be flagged."""
    bad, _ = _copy(ours, tmp_path)
    for p in bad.glob("pair_*.png"):
        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(p), np.roll(img, 1, axis=1))
    s = chk.check_dataset(bad)
    assert not s["ok"] and s["model_fit"]["bias_px"][0] > 0.5


def test_catches_wrong_pattern_phase(ours: Path, tmp_path: Path) -> None:
    """Truth rolled by one column (R -> R Rz(beta), same corner positions, new indices): patch colours
    then contradict the pattern."""
    bad, truth = _copy(ours, tmp_path)
    errors: list[str] = []
    _, left, right = chk.check_calib(bad / "calib.yaml", errors)  # type: ignore[misc]
    marker = chk.check_marker(bad / "marker.yaml", errors)
    assert marker is not None
    b = marker.beta
    Rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    a = b * np.arange(marker.columns)
    N = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    for e in truth:
        R = np.asarray(e["R"]) @ Rz
        t = np.asarray(e["t"])
        e["R"] = R.tolist()
        X = t + marker.corners() @ R.T
        for side, cam in (("left", left), ("right", right)):
            uv = chk.project(cam, X)
            cv = chk.cos_view(cam, X, N @ R.T)
            e[f"corners_{side}"] = [{"index": i, "uv": uv[i].tolist(), "cos_view": float(cv[i])}
                                    for i in range(marker.columns)]
    (bad / "truth.json").write_text(json.dumps(truth))
    s = chk.check_dataset(bad, model_fit=False)
    assert s["proj_err_max_px"] < 1e-6 and s["tip_err_max_m"] < 1e-9
    assert s["patches"]["wrong"] > 0.8 * s["patches"]["pairs_compared"]


def test_catches_bad_calib_and_marker(ours: Path, tmp_path: Path) -> None:
    bad, _ = _copy(ours, tmp_path)
    text = (bad / "calib.yaml").read_text().replace("image_size: [960, 540]", "image_size: [1920, 1080]")
    (bad / "calib.yaml").write_text(text)
    v = " ".join(chk.check_dataset(bad, model_fit=False)["violations"])
    assert "size 960x540 != calibrated (1920, 1080)" in v
    (bad / "marker.yaml").write_text("{radius: 4.55, columns: 11, row_height: 0.0025, tip_offset: 0.015}\n")
    v = " ".join(chk.check_dataset(bad, model_fit=False)["violations"])
    assert "columns must be an even integer" in v and "radius = 4.55" in v


def test_independent_renderer_obeys_the_contract(tmp_path: Path) -> None:
    """The independent renderer (another camera, a 14-column 4 mm marker, grey JPEG images) passes too."""
    out = tmp_path / "ind"
    ind.render_dataset(out, pairs=2, seed=4, scale=0.5, marker=ind.Marker(radius=0.004, columns=14),
                       look=ind.Look(jpeg=90, gray=True))
    s = chk.check_dataset(out)
    assert s["ok"], s["violations"]
    assert s["columns"] == 14 and s["model_fit"]["rms_px"] < chk.MODEL_RMS_TOL_PX
