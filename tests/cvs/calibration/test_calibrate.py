"""``wristmark calibrate``: on OpenCV's real stereo photographs against OpenCV's own pipeline run
here, on ChArUco pairs rendered with a known camera, outlier views, refusals and the report."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.cvs.calibration.load import load_calibration

PHOTOS = Path(__file__).resolve().parents[2] / "data" / "opencv_stereo"
NAMES = sorted(p.stem[4:] for p in PHOTOS.glob("left*.jpg"))
SQUARE = 0.025  # [m] any square size: lengths scale with it


def _photo_args() -> list[str]:
    return [str(PHOTOS / f"{side}{n}.jpg") for n in NAMES for side in ("left", "right")]


def _opencv_pipeline() -> tuple[float, np.ndarray, np.ndarray, float]:
    """findChessboardCornersSB + calibrateCamera per camera + stereoCalibrate (intrinsic guess)."""
    objp = np.zeros((54, 3), np.float32)
    objp[:, :2] = SQUARE * np.mgrid[0:9, 0:6].T.reshape(-1, 2)
    L, R = [], []
    for n in NAMES:
        for side, out in (("left", L), ("right", R)):
            g = cv2.imread(str(PHOTOS / f"{side}{n}.jpg"), cv2.IMREAD_GRAYSCALE)
            ok, c = cv2.findChessboardCornersSB(g, (9, 6), flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
            assert ok
            out.append(c)
    size = (g.shape[1], g.shape[0])
    obj = [objp] * len(NAMES)
    _, K1, D1, _, _ = cv2.calibrateCamera(obj, L, size, None, None)
    _, K2, D2, _, _ = cv2.calibrateCamera(obj, R, size, None, None)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-7)
    rms, K1, D1, K2, D2, _R, T, _E, _F = cv2.stereoCalibrate(obj, L, R, K1, D1, K2, D2, size,
                                                               flags=cv2.CALIB_USE_INTRINSIC_GUESS, criteria=crit)
    return float(rms), np.array([K1[0, 0], K1[1, 1]]), np.array([K2[0, 0], K2[1, 1]]), float(np.linalg.norm(T))


def test_real_photographs_match_opencv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, report = tmp_path / "c.yaml", tmp_path / "report"
    capsys.readouterr()
    assert main(["calibrate", "--board", f"chessboard:9x6:{SQUARE}", *_photo_args(), "--out", str(out),
                 "--report", str(report), "--json", "--no-progress"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["used"] == len(NAMES) == 13 and not res["dropped"]
    cv_rms, cv_fl, cv_fr, cv_base = _opencv_pipeline()
    cam = load_calibration(out)
    assert res["rms_px"] < 0.25 and res["rms_px"] <= 1.05 * cv_rms, (res["rms_px"], cv_rms)
    np.testing.assert_allclose([cam.left.K[0, 0], cam.left.K[1, 1]], cv_fl, rtol=0.01)
    np.testing.assert_allclose([cam.right.K[0, 0], cam.right.K[1, 1]], cv_fr, rtol=0.01)
    assert abs(cam.baseline - cv_base) < 0.01 * cv_base
    assert cam.image_size == (640, 480)
    text = (report / "report.md").read_text()
    assert all(f"left{n}.jpg + right{n}.jpg" in text for n in NAMES)
    for png in ("coverage_left.png", "coverage_right.png", "rectified_pair.png"):
        img = cv2.imread(str(report / png))
        assert img is not None and img.std() > 5
    assert cv2.imread(str(report / "rectified_pair.png")).shape == (480, 1280, 3)
    # an existing --out is refused without --force
    assert main(["calibrate", "--board", f"chessboard:9x6:{SQUARE}", *_photo_args(), "--out", str(out),
                 "--no-progress"]) == 2
    assert "--force" in capsys.readouterr().err


def test_calibrate_from_a_source_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "ds"
    folder.mkdir()
    for k, n in enumerate(NAMES):
        for side in ("left", "right"):
            shutil.copy(PHOTOS / f"{side}{n}.jpg", folder / f"pair_{k:02d}_{side}.jpg")
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    assert main(["calibrate", "--board", f"chessboard:9x6:{SQUARE}", "--source", str(folder), "--out", str(a),
                 "--no-progress"]) == 0
    assert main(["calibrate", "--board", f"chessboard:9x6:{SQUARE}", *_photo_args(), "--out", str(b),
                 "--no-progress"]) == 0
    ca, cb = load_calibration(a), load_calibration(b)
    np.testing.assert_allclose(ca.left.K, cb.left.K, rtol=1e-9)
    np.testing.assert_allclose(ca.T, cb.T, rtol=1e-9, atol=1e-12)


def test_mismatched_pair_is_dropped_and_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "photos"
    shutil.copytree(PHOTOS, folder)
    shutil.copy(folder / "right06.jpg", folder / "right05.jpg")  # pair 05 no longer a stereo pair
    args = [str(folder / f"{side}{n}.jpg") for n in NAMES for side in ("left", "right")]
    capsys.readouterr()
    assert main(["calibrate", "--board", f"chessboard:9x6:{SQUARE}", *args, "--out", str(tmp_path / "c.yaml"),
                 "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "dropped view left05.jpg + right05.jpg" in err
    assert sum("dropped view" in line for line in err.splitlines()) == 1


# --- ChArUco pairs rendered with a known camera -------------------------------------------------
SIZE = (640, 480)
K1 = np.array([[600.0, 0, 322.0], [0, 602.0, 236.0], [0, 0, 1]])
D1 = np.array([-0.22, 0.06, 0.0008, -0.0004, 0.0])
K2 = np.array([[605.0, 0, 317.0], [0, 604.0, 243.0], [0, 0, 1]])
D2 = np.array([-0.2, 0.05, -0.0005, 0.0003, 0.0])
R_LR = cv2.Rodrigues(np.array([0.004, -0.03, 0.002]))[0]
T_LR = np.array([-0.03, 0.0006, 0.0004])  # [m]
COLS, ROWS, SQ, MK, MARGIN, PX = 7, 5, 0.02, 0.014, 40, 100  # board: squares, sizes [m], image margin/px per square


def _rays(K: np.ndarray, D: np.ndarray, s: int = 2) -> np.ndarray:
    """Normalised undistorted image point of every pixel of the image rendered at s x (N, 2)."""
    Ks = K.copy()
    Ks[:2] *= s
    Ks[0, 2], Ks[1, 2] = (K[0, 2] + 0.5) * s - 0.5, (K[1, 2] + 0.5) * s - 0.5
    w, h = SIZE[0] * s, SIZE[1] * s
    uv = np.stack(np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)), -1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    return cv2.undistortPoints(uv, Ks, D, None, None, None, crit).reshape(-1, 2)


def _render(board_img: np.ndarray, rays: np.ndarray, R: np.ndarray, t: np.ndarray,
            rng: np.random.Generator, s: int = 2) -> np.ndarray:
    """The board (pose R, t in this camera) seen through the camera of ``rays`` (_rays): each
    pixel's ray is taken to the board plane by the inverse homography, sampled by cv2.remap at
    s x, blurred a little and averaged down, with sensor noise."""
    w, h = SIZE[0] * s, SIZE[1] * s
    H = np.column_stack([R[:, 0], R[:, 1], t])  # board (X, Y, 1) -> normalised image point
    XY = np.linalg.solve(H, np.c_[rays, np.ones(len(rays))].T).T
    XY = XY[:, :2] / XY[:, 2:3]
    mx = (MARGIN + XY[:, 0] / SQ * PX - 0.5).reshape(h, w).astype(np.float32)
    my = (MARGIN + XY[:, 1] / SQ * PX - 0.5).reshape(h, w).astype(np.float32)
    img = cv2.remap(board_img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=90)
    img = cv2.resize(cv2.GaussianBlur(img, (0, 0), 0.8), SIZE, interpolation=cv2.INTER_AREA).astype(np.float64)
    return np.clip(0.8 * img + 25 + rng.normal(0, 1.5, img.shape), 0, 255).astype(np.uint8)


def _charuco_pairs(folder: Path) -> list[str]:
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100)
    board = cv2.aruco.CharucoBoard((COLS, ROWS), SQ, MK, d)
    board_img = board.generateImage((COLS * PX + 2 * MARGIN, ROWS * PX + 2 * MARGIN), marginSize=MARGIN)
    rng = np.random.default_rng(3)
    centre = np.array([COLS * SQ / 2, ROWS * SQ / 2, 0.0])
    paths = []
    rays = {"left": _rays(K1, D1), "right": _rays(K2, D2)}
    for k in range(14):
        rvec = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)])
        R = cv2.Rodrigues(rvec)[0]
        z = rng.uniform(0.22, 0.32)
        target = np.array([rng.uniform(-0.25, 0.25) * z, rng.uniform(-0.18, 0.18) * z, z])
        t = target - R @ centre
        for side, (Rc, tc) in (("left", (R, t)), ("right", (R_LR @ R, R_LR @ t + T_LR))):
            p = folder / f"{side}_{k:02d}.png"
            cv2.imwrite(str(p), _render(board_img, rays[side], Rc, tc, rng))
            paths.append(str(p))
    return paths


@pytest.mark.slow
def test_charuco_rendered_known_camera(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    paths = _charuco_pairs(tmp_path)
    out = tmp_path / "c.yaml"
    capsys.readouterr()
    assert main(["calibrate", "--board", f"charuco:{COLS}x{ROWS}:{SQ}:{MK}:DICT_5X5_100", *paths,
                 "--out", str(out), "--json", "--no-progress"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["used"] >= 12, res
    cam = load_calibration(out)
    for got, K in ((cam.left.K, K1), (cam.right.K, K2)):
        np.testing.assert_allclose([got[0, 0], got[1, 1]], [K[0, 0], K[1, 1]], rtol=0.005)
        assert np.hypot(got[0, 2] - K[0, 2], got[1, 2] - K[1, 2]) < 2.0
    assert abs(cam.baseline - np.linalg.norm(T_LR)) < 0.01 * np.linalg.norm(T_LR)
    assert res["rms_px"] < 0.3


@pytest.mark.parametrize(("argv", "needle"), [
    (["--board", "chessboard:9x6"], "expected chessboard:CxR:SQUARE"),
    (["--board", "chessboard:9x6:25"], "metres, not mm"),
    (["--board", "charuco:7x5:0.02:0.03:DICT_5X5_100"], "MARKER < SQUARE"),
    (["--board", "charuco:7x5:0.02:0.014:DICT_NOPE"], "unknown ArUco dictionary 'DICT_NOPE'"),
])
def test_bad_board_specs(tmp_path: Path, argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["calibrate", *argv, *_photo_args()[:2], "--out", str(tmp_path / "c.yaml")]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1


def test_too_few_views_and_odd_paths(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["calibrate", "--board", "chessboard:9x6:0.025", *_photo_args()[:4], "--out",
                 str(tmp_path / "c.yaml"), "--no-progress"]) == 2
    assert "need >= 3" in capsys.readouterr().err
    assert main(["calibrate", "--board", "chessboard:9x6:0.025", *_photo_args()[:3], "--out",
                 str(tmp_path / "c.yaml")]) == 2
    assert "LEFT RIGHT pairs" in capsys.readouterr().err
    assert not (tmp_path / "c.yaml").exists()
