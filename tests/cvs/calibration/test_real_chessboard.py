"""Our X-corner stage (CL, HTM test, sub-pixel fit) + grid assembly on real photographs against
cv2.findChessboardCornersSB: OpenCV's 13 stereo sample pairs (tests/data/opencv_stereo, Apache-2.0,
see its README), 9x6 inner corners, 640x480 JPEG."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cvs.corners.detector import assemble_grid, detect_xcorners

pytestmark = [pytest.mark.slow]

DATA = Path(__file__).resolve().parents[2] / "data" / "opencv_stereo"
IDS = ("01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14")
PATTERN = (9, 6)
SIZE = (640, 480)
Corners = dict[str, dict[str, list[np.ndarray | None]]]


def _opencv(g: np.ndarray) -> np.ndarray | None:
    ok, c = cv2.findChessboardCornersSB(g, PATTERN, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    return c.reshape(-1, 2).astype(np.float64) if ok else None


@pytest.fixture(scope="module")
def corners() -> Corners:
    """method -> side -> per pair (54, 2) corners or None."""
    cv2.setNumThreads(1)
    out: Corners = {m: {"left": [], "right": []} for m in ("ours", "opencv")}
    for i in IDS:
        for side in ("left", "right"):
            g = cv2.imread(str(DATA / f"{side}{i}.jpg"), cv2.IMREAD_GRAYSCALE)
            assert g is not None and g.shape == (SIZE[1], SIZE[0])
            out["ours"][side].append(assemble_grid(detect_xcorners(g), PATTERN, g))
            out["opencv"][side].append(_opencv(g))
    return out


def _stereo_rms(left: list[np.ndarray | None], right: list[np.ndarray | None]) -> tuple[float, np.ndarray]:
    """Each camera calibrated alone, then cv2.stereoCalibrate from that guess: RMS [px], T."""
    keep = [k for k in range(len(left)) if left[k] is not None and right[k] is not None]
    objp = np.zeros((PATTERN[0] * PATTERN[1], 3), np.float32)
    objp[:, :2] = np.mgrid[0 : PATTERN[0], 0 : PATTERN[1]].T.reshape(-1, 2)
    obj = [objp] * len(keep)
    L = [np.asarray(left[k], np.float32).reshape(-1, 1, 2) for k in keep]
    R = [np.asarray(right[k], np.float32).reshape(-1, 1, 2) for k in keep]
    _, K1, D1, _, _ = cv2.calibrateCamera(obj, L, SIZE, None, None)
    _, K2, D2, _, _ = cv2.calibrateCamera(obj, R, SIZE, None, None)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-6)
    rms, *_, T, _, _ = cv2.stereoCalibrate(
        obj, L, R, K1, D1, K2, D2, SIZE, flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=crit
    )
    return float(rms), np.asarray(T, float).ravel()


def test_data_and_licence_are_shipped() -> None:
    assert len(list(DATA.glob("*.jpg"))) == 2 * len(IDS)
    assert "Apache License" in (DATA / "LICENSE").read_text()
    readme = (DATA / "README.md").read_text()
    assert "opencv_python_headless-5.0.0.93" in readme and "Apache License 2.0" in readme


def test_detection_count_at_least_opencv(corners: Corners) -> None:
    n = {m: sum(c is not None for side in d.values() for c in side) for m, d in corners.items()}
    print(f"\ncomplete 9x6 grids: ours {n['ours']}/26, findChessboardCornersSB {n['opencv']}/26")
    assert n["ours"] >= n["opencv"]
    assert n["ours"] == 2 * len(IDS)


def test_mean_distance_to_opencv_per_image(corners: Corners) -> None:
    """Same corners in the same order: mean distance per image below 0.5 px."""
    means = []
    for side in ("left", "right"):
        for ours, cv in zip(corners["ours"][side], corners["opencv"][side]):
            if ours is not None and cv is not None:
                means.append(float(np.mean(np.hypot(*(ours - cv).T))))
    print("\nmean distance ours vs OpenCV per image [px]:", np.round(means, 3).tolist())
    assert len(means) == 2 * len(IDS)
    assert max(means) < 0.5


def test_stereo_calibration_rms_no_worse_than_opencv(corners: Corners) -> None:
    rms_ours, T_ours = _stereo_rms(corners["ours"]["left"], corners["ours"]["right"])
    rms_cv, T_cv = _stereo_rms(corners["opencv"]["left"], corners["opencv"]["right"])
    print(f"\nstereoCalibrate RMS [px]: ours {rms_ours:.4f}, findChessboardCornersSB {rms_cv:.4f}")
    assert rms_ours <= rms_cv
    assert np.linalg.norm(T_ours - T_cv) < 0.02 * np.linalg.norm(T_cv)  # same rig (squares as unit)
