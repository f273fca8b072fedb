"""Stereo dataset folder: write and read back (docs/design.md "Stereo dataset format")."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.dataset import DatasetWriter, load_dataset
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import StereoRenderer

DEFAULT = CONFIG_DIR / "camera.yaml"


def test_round_trip(tmp_path: Path) -> None:
    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    marker = MarkerModel()
    r = StereoRenderer(cam, marker, RenderSettings(), seed=2)
    w = DatasetWriter(tmp_path / "ds", cam, marker)
    frames = [r.render(arm_shape(RobotParams(), np.array(HOME_PSI) + [0.05 * k, 0, 0, 0, 0, 0])) for k in range(2)]
    assert [w.add(f) for f in frames] == [0, 1]
    ds = load_dataset(tmp_path / "ds")
    assert ds.camera.image_size == cam.image_size and ds.marker == marker
    assert [p[0].name for p in ds.pairs] == ["pair_00_left.png", "pair_01_left.png"]
    for f, t, (lp, rp) in zip(frames, ds.truth, ds.pairs):
        np.testing.assert_allclose(t.R, f.T_left_marker[:3, :3], atol=1e-15)
        np.testing.assert_allclose(t.t, f.T_left_marker[:3, 3], atol=1e-15)
        np.testing.assert_allclose(t.tip, f.tip_left, atol=1e-15)
        assert t.corners_left == f.corners_left and t.corners_right == f.corners_right
        assert np.array_equal(cv2.imread(str(lp)), f.left) and np.array_equal(cv2.imread(str(rp)), f.right)
    raw = json.loads((tmp_path / "ds" / "truth.json").read_text())
    assert set(raw[0]) == {"pair", "R", "t", "tip", "corners_left", "corners_right"}
    assert set(raw[0]["corners_left"][0]) == {"index", "uv", "cos_view"}
    assert len(raw[0]["corners_right"]) == marker.columns


def test_load_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        load_dataset(tmp_path / "missing")
    cam = scaled_stereo_camera(load_calibration(DEFAULT), 0.25)
    DatasetWriter(tmp_path / "ds", cam, MarkerModel())
    with pytest.raises(InputError, match="truth.json"):
        load_dataset(tmp_path / "ds")
    (tmp_path / "ds" / "truth.json").write_text('[{"pair": 0}]')
    with pytest.raises(InputError, match="malformed truth"):
        load_dataset(tmp_path / "ds")
