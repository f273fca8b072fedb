"""The fast renderer's glossy sleeve: a clipped highlight stripe along the sleeve from the
lights beside the lenses (RenderSettings.sleeve_specular), off by default."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wristmark.cli.render import psi_spread
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.render.settings import RenderSettings, noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.visibility import random_visible_psi

P = RobotParams()


def square_poses(camera: StereoCamera, marker: MarkerModel, n: int, seed: int = 0,
                 max_tilt_deg: float = 4.0) -> list[np.ndarray]:
    """n random visible configurations whose sleeve axis lies within ``max_tilt_deg`` of square
    to the left camera's line of sight (where the coaxial highlight runs along the sleeve)."""
    rng = np.random.default_rng(seed)
    T_lw = np.linalg.inv(np.asarray(camera.T_world_left, float))
    out: list[np.ndarray] = []
    while len(out) < n:
        q = random_visible_psi(P, camera, marker, rng, psi_spread(P), 400)
        T = T_lw @ arm_shape(P, q).T_world_marker
        o, z = T[:3, 3], T[:3, 2]
        if np.degrees(np.arcsin(abs(float(z @ o)) / float(np.linalg.norm(o)))) <= max_tilt_deg:
            out.append(q)
    return out


@pytest.fixture(scope="module")
def half_camera() -> StereoCamera:
    return scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.5)


def test_the_glossy_settings_are_validated() -> None:
    for key, bad in (("sleeve_specular", -0.1), ("sleeve_specular", 1.5), ("sleeve_roughness", 0.0),
                     ("light_offset", 0.05)):
        with pytest.raises(ConfigError, match=key):
            dataclasses.replace(RenderSettings(), **{key: bad}).validate()  # type: ignore[arg-type]


def test_a_matte_sleeve_renders_exactly_as_before(half_camera: StereoCamera) -> None:
    # the laminate's other keys do nothing while sleeve_specular is 0: today's images, bit for bit
    shape = arm_shape(P, square_poses(half_camera, MarkerModel(), 1)[0])
    a = StereoRenderer(half_camera, MarkerModel(), noise_preset("none"), seed=2).signal(shape)
    b = StereoRenderer(half_camera, MarkerModel(), noise_preset("none", sleeve_roughness=0.03, light_offset=0.003),
                       seed=2).signal(shape)
    np.testing.assert_array_equal(a, b)


def test_a_glossy_sleeve_square_to_the_view_gets_a_clipped_stripe(half_camera: StereoCamera) -> None:
    marker = MarkerModel()
    q = square_poses(half_camera, marker, 1)[0]
    shape = arm_shape(P, q)
    matte = StereoRenderer(half_camera, marker, noise_preset("none"), seed=2).render(shape)
    gloss = StereoRenderer(half_camera, marker, noise_preset("none", sleeve_specular=0.04, sleeve_roughness=0.05),
                           seed=2).render(shape)
    diff = gloss.left.astype(int).max(axis=2) - matte.left.astype(int).max(axis=2)
    assert diff.min() >= 0  # the laminate only adds light
    changed = diff > 40
    clipped = changed & (gloss.left.max(axis=2) == 255)  # at the sensor's full well
    assert clipped.sum() > 20
    # on black patches too: a corner under the stripe loses its dark sectors
    assert np.count_nonzero(clipped & (matte.left.max(axis=2) < 60)) > 5
    # the stripe lies on the sleeve, inside the hull of its visible corners grown by a row height
    uv = np.array([c.uv for c in matte.corners_left if c.cos_view > 0])
    vs, us = np.nonzero(changed)
    grow = 60.0
    assert np.all((us >= uv[:, 0].min() - grow) & (us <= uv[:, 0].max() + grow))
    assert np.all((vs >= uv[:, 1].min() - grow) & (vs <= uv[:, 1].max() + grow))


def test_a_tilted_sleeve_shows_almost_no_highlight(half_camera: StereoCamera) -> None:
    # 25 degrees or more from square: the coaxial light's mirror direction misses the camera
    marker = MarkerModel()
    rng = np.random.default_rng(1)
    T_lw = np.linalg.inv(np.asarray(half_camera.T_world_left, float))
    while True:
        q = random_visible_psi(P, half_camera, marker, rng, psi_spread(P), 400)
        T = T_lw @ arm_shape(P, q).T_world_marker
        if np.degrees(np.arcsin(abs(float(T[:3, 2] @ T[:3, 3])) / float(np.linalg.norm(T[:3, 3])))) > 25:
            break
    shape = arm_shape(P, q)
    a = StereoRenderer(half_camera, marker, noise_preset("none"), seed=2).signal(shape)
    b = StereoRenderer(half_camera, marker, noise_preset("none", sleeve_specular=0.04, sleeve_roughness=0.1),
                       seed=2).signal(shape)
    assert float(np.max(b - a)) < 10.0
