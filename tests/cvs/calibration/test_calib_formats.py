"""Calibration files labs have: ROS camera_info pairs, Kalibr camchains, OpenCV XML, against
hand-computed values; the round trip through ``wristmark calib convert``; every refusal."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from wristmark.cli.main import main
from wristmark.cvs.calibration.load import load_calibration
from wristmark.models.errors import ConfigError

K_L = [[1380.0, 0.0, 959.5], [0.0, 1381.0, 539.5], [0.0, 0.0, 1.0]]
K_R = [[1383.0, 0.0, 962.0], [0.0, 1382.0, 537.0], [0.0, 0.0, 1.0]]
D_L = [-0.25, 0.08, 0.001, -0.0005, 0.0]
D_R = [-0.245, 0.075, 0.0, 0.0002, 0.0]


def _rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ros_file(path: Path, K, D, R, P, size=(1920, 1080), model="plumb_bob", name="left") -> Path:
    data = {
        "image_width": size[0], "image_height": size[1], "camera_name": f"endoscope/{name}",
        "camera_matrix": {"rows": 3, "cols": 3, "data": np.ravel(K).tolist()},
        "distortion_model": model,
        "distortion_coefficients": {"rows": 1, "cols": len(D), "data": list(D)},
        "rectification_matrix": {"rows": 3, "cols": 3, "data": np.ravel(R).tolist()},
        "projection_matrix": {"rows": 3, "cols": 4, "data": np.ravel(P).tolist()},
    }
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _ros_pair(tmp_path: Path, **right_changes) -> tuple[str, np.ndarray, np.ndarray]:
    """A pair with rectifications R1 = Ry(0.02) Rx(0.01), R2 = Ry(0.015) Rx(-0.004) and a 5 mm
    baseline: Tx = P2[0,3] = -fx' * 0.005 with fx' = 1300 px."""
    R1 = _rot_y(0.02) @ _rot_x(0.01)
    R2 = _rot_y(0.015) @ _rot_x(-0.004)
    P1 = [[1300.0, 0, 950.0, 0], [0, 1300.0, 540.0, 0], [0, 0, 1, 0]]
    P2 = [[1300.0, 0, 950.0, -1300.0 * 0.005], [0, 1300.0, 540.0, 0], [0, 0, 1, 0]]
    left = _ros_file(tmp_path / "left.yaml", K_L, D_L, R1, P1)
    kw = {"K": K_R, "D": D_R, "R": R2, "P": P2, "name": "right"} | right_changes
    right = _ros_file(tmp_path / "right.yaml", **kw)
    return f"{left},{right}", R1, R2


def test_ros_pair_hand_computed(tmp_path: Path) -> None:
    spec, R1, R2 = _ros_pair(tmp_path)
    cam = load_calibration(spec)
    # R = R2^T R1, T = R2^T [Tx / fx', 0, 0] with Tx / fx' = -0.005 m
    np.testing.assert_allclose(cam.R, R2.T @ R1, atol=1e-12)
    np.testing.assert_allclose(cam.T, R2.T @ np.array([-0.005, 0.0, 0.0]), atol=1e-12)
    np.testing.assert_allclose(cam.left.K, K_L)
    np.testing.assert_allclose(cam.right.dist, D_R)
    assert cam.image_size == (1920, 1080)
    assert abs(cam.baseline - 0.005) < 1e-12
    # a point seen by both raw cameras lands on one rectified row, as ROS's P1 R1 / P2 R2 predict
    X = np.array([0.004, -0.003, 0.08])
    xr = cam.R @ X + cam.T
    v1 = (np.array(K_L[1]) @ (R1 @ X) / (R1 @ X)[2])
    v2 = (np.array(K_L[1]) @ (R2 @ xr) / (R2 @ xr)[2])
    assert abs(v1 - v2) < 1e-9


def test_ros_pair_from_opencv_rectification(tmp_path: Path) -> None:
    """R1, R2, P2 as cv2.stereoRectify (and so ROS's camera_calibration) makes them for a known rig:
    the loader gives that rig back."""
    R_true = cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0]
    T_true = np.array([-0.0049, 0.0003, 0.0002])
    R1, R2, P1, P2, *_ = cv2.stereoRectify(np.array(K_L), np.array(D_L), np.array(K_R), np.array(D_R), (1920, 1080),
                                           R_true, T_true.reshape(3, 1))
    left = _ros_file(tmp_path / "l.yaml", K_L, D_L, R1, P1)
    right = _ros_file(tmp_path / "r.yaml", K_R, D_R, R2, P2)
    cam = load_calibration(f"{left},{right}")
    np.testing.assert_allclose(cam.R, R_true, atol=1e-9)
    np.testing.assert_allclose(cam.T, T_true, atol=1e-9)


def _kalibr(path: Path, **changes) -> Path:
    T = np.eye(4)
    T[:3, :3] = _rot_y(0.003)
    T[:3, 3] = [-0.00502, 0.0001, -0.00003]
    data = {
        "cam0": {"camera_model": "pinhole", "intrinsics": [1380.0, 1381.0, 959.5, 539.5],
                 "distortion_model": "radtan", "distortion_coeffs": [-0.25, 0.08, 0.001, -0.0005],
                 "resolution": [1920, 1080], "rostopic": "/stereo/left/image_raw"},
        "cam1": {"camera_model": "pinhole", "intrinsics": [1383.0, 1382.0, 962.0, 537.0],
                 "distortion_model": "radtan", "distortion_coeffs": [-0.245, 0.075, 0.0, 0.0002],
                 "resolution": [1920, 1080], "T_cn_cnm1": T.tolist(), "rostopic": "/stereo/right/image_raw"},
    }
    for key, value in changes.items():
        cam, field = key.split("__")
        if value is None:
            data[cam].pop(field)
        else:
            data[cam][field] = value
    path.write_text(yaml.safe_dump(data))
    return path


def test_kalibr_camchain_hand_computed(tmp_path: Path) -> None:
    cam = load_calibration(_kalibr(tmp_path / "camchain.yaml"))
    np.testing.assert_allclose(cam.left.K, K_L)
    np.testing.assert_allclose(cam.right.K, K_R)
    np.testing.assert_allclose(cam.left.dist, D_L)
    np.testing.assert_allclose(cam.right.dist, D_R)
    np.testing.assert_allclose(cam.R, _rot_y(0.003), atol=1e-12)
    np.testing.assert_allclose(cam.T, [-0.00502, 0.0001, -0.00003], atol=1e-15)
    assert cam.image_size == (1920, 1080)


def test_opencv_xml_hand_computed(tmp_path: Path) -> None:
    path = tmp_path / "stereo.xml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for k, v in (("M1", K_L), ("D1", [D_L]), ("M2", K_R), ("D2", [D_R]), ("R", _rot_x(0.002)),
                 ("T", [[-0.005], [0.0], [0.0001]])):
        fs.write(k, np.asarray(v, float))
    fs.write("image_width", 1920)
    fs.write("image_height", 1080)
    fs.release()
    assert path.read_text().lstrip().startswith("<?xml")
    cam = load_calibration(path)
    np.testing.assert_allclose(cam.left.K, K_L)
    np.testing.assert_allclose(cam.right.dist, D_R)
    np.testing.assert_allclose(cam.R, _rot_x(0.002), atol=1e-15)
    np.testing.assert_allclose(cam.T, [-0.005, 0.0, 0.0001])
    assert cam.image_size == (1920, 1080)


@pytest.mark.parametrize("form", ["ros", "kalibr", "xml"])
def test_round_trip_through_calib_convert(tmp_path: Path, form: str, capsys: pytest.CaptureFixture[str]) -> None:
    if form == "ros":
        spec = _ros_pair(tmp_path)[0]
    elif form == "kalibr":
        spec = str(_kalibr(tmp_path / "camchain.yaml"))
    else:
        spec = str(tmp_path / "s.xml")
        fs = cv2.FileStorage(spec, cv2.FILE_STORAGE_WRITE)
        for k, v in (("M1", K_L), ("D1", [D_L]), ("M2", K_R), ("D2", [D_R]), ("R", np.eye(3)),
                     ("T", [[-0.005], [0.0], [0.0]])):
            fs.write(k, np.asarray(v, float))
        fs.release()
    out = tmp_path / "c.yaml"
    assert main(["calib", "convert", "--calib", spec, "--out", str(out)]) == 0
    a, b = load_calibration(spec), load_calibration(out)
    assert a.image_size == b.image_size
    for x, y in ((a.left.K, b.left.K), (a.right.K, b.right.K), (a.left.dist, b.left.dist),
                 (a.right.dist, b.right.dist), (a.R, b.R), (a.T, b.T)):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-15)
    assert main(["calib", "convert", "--calib", spec, "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err


def test_calib_show_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = str(_kalibr(tmp_path / "camchain.yaml"))
    capsys.readouterr()
    assert main(["calib", "show", "--calib", spec, "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["left"]["fx"] == 1380.0 and s["right"]["cy"] == 537.0
    assert abs(s["baseline_mm"] - 1000 * np.linalg.norm([-0.00502, 0.0001, -0.00003])) < 1e-9
    # pinhole field of view: 2 atan(w / 2 fx), 2 atan(h / 2 fy)
    assert abs(s["left"]["hfov_deg"] - np.degrees(2 * np.arctan(1920 / (2 * 1380.0)))) < 0.05
    assert abs(s["left"]["vfov_deg"] - np.degrees(2 * np.arctan(1080 / (2 * 1381.0)))) < 0.05
    # 5 mm at 80 mm is ~86 px of disparity over 1920 px: the overlap drops by ~4.5 %
    assert 90.0 < s["overlap_at_working_distance_pct"] < s["rectified_overlap_pct"] <= 100.0
    assert main(["calib", "show", "--calib", spec]) == 0
    text = capsys.readouterr().out
    assert "baseline: 5.021 mm" in text and "field of view" in text


def _xml(tmp_path: Path, **mats) -> Path:
    path = tmp_path / "bad.xml"
    base = {"M1": K_L, "D1": [D_L], "M2": K_R, "D2": [D_R], "R": np.eye(3), "T": [[-0.005], [0.0], [0.0]]} | mats
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for k, v in base.items():
        fs.write(k, np.asarray(v, float))
    fs.release()
    return path


REFUSALS = [
    ("ros_fisheye", "fisheye/equidistant"),
    ("kalibr_equidistant", "fisheye/equidistant"),
    ("kalibr_omni", "only 'pinhole'"),
    ("kalibr_missing_T", "missing key 'cam1.T_cn_cnm1'"),
    ("ros_missing_P", "missing key 'projection_matrix'"),
    ("xml_3x4", "'M1' is 3x4"),
    ("ros_3x4", "'camera_matrix' is 3x4"),
    ("xml_mm", "looks like millimetres"),
    ("kalibr_mm", "looks like millimetres"),
    ("ros_sizes", "differ in size (1920x1080 vs 1280x720)"),
    ("kalibr_sizes", "differ in size"),
    ("ros_single", "give the pair as LEFT.yaml,RIGHT.yaml"),
]


def _refused(tmp_path: Path, case: str) -> str:
    if case == "ros_fisheye":
        return _ros_pair(tmp_path, model="equidistant", D=[0.1, 0.01, 0.0, 0.0])[0]
    if case == "kalibr_equidistant":
        return str(_kalibr(tmp_path / "k.yaml", cam1__distortion_model="equidistant"))
    if case == "kalibr_omni":
        return str(_kalibr(tmp_path / "k.yaml", cam0__camera_model="omni"))
    if case == "kalibr_missing_T":
        return str(_kalibr(tmp_path / "k.yaml", cam1__T_cn_cnm1=None))
    if case == "ros_missing_P":
        spec = _ros_pair(tmp_path)[0]
        right = Path(spec.split(",")[1])
        d = yaml.safe_load(right.read_text())
        d.pop("projection_matrix")
        right.write_text(yaml.safe_dump(d))
        return spec
    if case == "xml_3x4":
        return str(_xml(tmp_path, M1=np.c_[np.array(K_L), np.zeros(3)]))
    if case == "ros_3x4":
        spec = _ros_pair(tmp_path)[0]
        left = Path(spec.split(",")[0])
        d = yaml.safe_load(left.read_text())
        d["camera_matrix"] = {"rows": 3, "cols": 4, "data": np.c_[np.array(K_L), np.zeros(3)].ravel().tolist()}
        left.write_text(yaml.safe_dump(d))
        return spec
    if case == "xml_mm":
        return str(_xml(tmp_path, T=[[-5.0], [0.0], [0.0]]))
    if case == "kalibr_mm":
        T = np.eye(4)
        T[0, 3] = -5.02
        return str(_kalibr(tmp_path / "k.yaml", cam1__T_cn_cnm1=T.tolist()))
    if case == "ros_sizes":
        return _ros_pair(tmp_path, size=(1280, 720))[0]
    if case == "kalibr_sizes":
        return str(_kalibr(tmp_path / "k.yaml", cam1__resolution=[1280, 720]))
    return _ros_pair(tmp_path)[0].split(",")[0]


@pytest.mark.parametrize(("case", "needle"), REFUSALS)
def test_refusals_are_one_line_with_the_fix(tmp_path: Path, case: str, needle: str,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    spec = _refused(tmp_path, case)
    with pytest.raises(ConfigError) as e:
        load_calibration(spec)
    assert needle in str(e.value) and "\n" not in str(e.value)
    capsys.readouterr()
    assert main(["calib", "show", "--calib", spec]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err
