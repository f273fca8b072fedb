"""Calibration files: YAML and OpenCV FileStorage round trips and every documented error."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from wristmark.cvs.calibration.load import calibration_mapping, load_calibration, save_calibration
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError

DEFAULT = CONFIG_DIR / "camera.yaml"


def _same(a, b) -> None:
    assert a.image_size == b.image_size
    for x, y in ((a.left.K, b.left.K), (a.left.dist, b.left.dist), (a.right.K, b.right.K), (a.R, b.R), (a.T, b.T)):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)


def test_yaml_round_trip(tmp_path: Path) -> None:
    cam = load_calibration(DEFAULT)
    assert cam.T_world_left is not None
    save_calibration(tmp_path / "c.yaml", cam)
    back = load_calibration(tmp_path / "c.yaml")
    _same(cam, back)
    np.testing.assert_allclose(back.T_world_left, cam.T_world_left, atol=1e-12)


def test_opencv_filestorage_round_trip(tmp_path: Path) -> None:
    cam = load_calibration(DEFAULT)
    path = tmp_path / "stereo.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("M1", cam.left.K)
    fs.write("D1", cam.left.dist.reshape(1, 5))
    fs.write("M2", cam.right.K)
    fs.write("D2", cam.right.dist.reshape(1, 5))
    fs.write("R", cam.R)
    fs.write("T", cam.T.reshape(3, 1))
    fs.write("image_size", np.array([[1920, 1080]], dtype=np.int32))
    fs.release()
    back = load_calibration(path)
    _same(cam, back)
    assert back.T_world_left is None


def test_opencv_without_size_uses_principal_point(tmp_path: Path) -> None:
    cam = load_calibration(DEFAULT)
    path = tmp_path / "stereo.xml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for k, v in (("M1", cam.left.K), ("D1", cam.left.dist), ("M2", cam.right.K), ("D2", cam.right.dist)):
        fs.write(k, np.asarray(v, float))
    fs.write("R", cam.R)
    fs.write("T", cam.T)
    fs.release()
    assert load_calibration(path).image_size == (1920, 1080)


def _write(tmp_path: Path, mutate) -> Path:
    data = calibration_mapping(load_calibration(DEFAULT))
    mutate(data)
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


@pytest.mark.parametrize(
    ("mutate", "needle"),
    [
        (lambda d: d["left"].__setitem__("K", [[1, 0], [0, 1]]), "left.K"),
        (lambda d: d["right"]["K"][0].__setitem__(0, -5.0), "focal"),
        (lambda d: d.__setitem__("R", [[1, 0, 0], [0, 1, 0], [0, 0, -1]]), "'R'"),
        (lambda d: d.__setitem__("R", [[2, 0, 0], [0, 1, 0], [0, 0, 1]]), "'R'"),
        (lambda d: d.__setitem__("extra", 1), "unknown key 'extra'"),
        (lambda d: d["left"].__setitem__("foo", 1), "left.foo"),
        (lambda d: d.pop("T"), "missing key 'T'"),
        (lambda d: d.__setitem__("T", [0, 0]), "'T'"),
        (lambda d: d["left"].__setitem__("dist", [0.1, 0.2]), "left.dist"),
        (lambda d: d.__setitem__("image_size", [1920]), "image_size"),
        (lambda d: d.__setitem__("world_T_left", [[1, 0, 0], [0, 1, 0], [0, 0, 1]]), "world_T_left"),
    ],
)
def test_yaml_errors_name_key_and_file(tmp_path: Path, mutate, needle: str) -> None:
    p = _write(tmp_path, mutate)
    with pytest.raises(ConfigError) as e:
        load_calibration(p)
    msg = str(e.value)
    assert needle in msg and str(p) in msg and "\n" not in msg


def test_missing_and_corrupt_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_calibration(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("image_size: [1920, 1080\nleft: {")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_calibration(bad)
    cv_bad = tmp_path / "bad.yml"
    cv_bad.write_text("%YAML:1.0\n---\nM1: !!opencv-matrix\n   rows: 3\n   cols: [\n")
    with pytest.raises(ConfigError, match=str(cv_bad)):
        load_calibration(cv_bad)


def test_opencv_missing_key(tmp_path: Path) -> None:
    path = tmp_path / "stereo.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("M1", np.eye(3))
    fs.release()
    with pytest.raises(ConfigError, match="missing key 'D1'"):
        load_calibration(path)
