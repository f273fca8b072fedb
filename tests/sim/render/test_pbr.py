"""The path tracer's parts that need no Mitsuba (sim.render.pbr): the sleeve's print, the pinhole
remap into the calibrated distortion, settings, and one clear line without the extra."""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.config_files import CONFIG_DIR, default_config
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.pbr import PbrSettings, PinholeRemap, load_mitsuba, sleeve_texture


@pytest.mark.parametrize("path", [None, "marker_coded.yaml"])
def test_the_sleeve_print_is_the_markers_pattern(path: str | None) -> None:
    m = MarkerModel.load(default_config(path)) if path else MarkerModel()
    tex = sleeve_texture(m, width=360)
    h, w = tex.shape[:2]
    z_lo, z_hi = m.z_extent
    rng = np.random.default_rng(0)
    for _ in range(300):  # texel centres: row 0 at z_lo, column 0 at angle 0 (Mitsuba's cylinder uv)
        i, j = int(rng.integers(h)), int(rng.integers(w))
        z = z_lo + (i + 0.5) / h * (z_hi - z_lo)
        a = (j + 0.5) / w * 2 * np.pi
        assert (tex[i, j, 0] < 0.5) == m.is_black(a, z)
    assert set(np.unique(tex)) == {np.float32(0.05), np.float32(0.86)}


def test_the_pinhole_remap_puts_a_point_where_the_camera_projects_it() -> None:
    cam = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.25).left
    size = (480, 270)
    rm = PinholeRemap(cam, size, margin=4)
    assert rm.width > size[0] and rm.height > size[1]
    rng = np.random.default_rng(1)
    P = np.column_stack([rng.uniform(-0.03, 0.03, 20), rng.uniform(-0.015, 0.015, 20), np.full(20, 0.1)])
    uv = cam.project(P)
    keep = (uv[:, 0] > 5) & (uv[:, 0] < size[0] - 6) & (uv[:, 1] > 5) & (uv[:, 1] < size[1] - 6)
    for (x, y, z), (u, v) in zip(P[keep], uv[keep]):
        # a smooth blob at the point's pinhole pixel (x f / z + W / 2 - 1/2), remapped
        px, py = x / z * rm.f + 0.5 * rm.width - 0.5, y / z * rm.f + 0.5 * rm.height - 0.5
        yy, xx = np.mgrid[0 : rm.height, 0 : rm.width]
        blob = np.exp(-((xx - px) ** 2 + (yy - py) ** 2) / (2 * 2.0**2)).astype(np.float32)
        raw = rm.remap(np.dstack([blob] * 3))[..., 0]
        vv, uu = np.mgrid[0 : size[1], 0 : size[0]]
        wgt = raw / raw.sum()
        assert abs(float((wgt * uu).sum()) - u) < 0.1 and abs(float((wgt * vv).sum()) - v) < 0.1


def test_settings_are_validated() -> None:
    PbrSettings().validate()
    for key, bad in (("spp", 0), ("sleeve_roughness", 0.0), ("light_offset", 0.1), ("aperture_radius", -1e-4),
                     ("focus_distance", 5.0), ("sleeve_specular", 0.7)):
        with pytest.raises(ConfigError, match=key):
            dataclasses.replace(PbrSettings(), **{key: bad}).validate()  # type: ignore[arg-type]


def test_without_mitsuba_one_clear_line_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # as if not installed
    with pytest.raises(InputError, match=r"wristmark\[pbr\]"):
        load_mitsuba()
