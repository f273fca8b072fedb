"""The scene file (sim.scene) and the scene's setup (sim.scene_setup): arms, bases, the camera that
frames them all, and bad scenes refused in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.sim.scene import Scene, pose_from_xyz_rpy
from wristmark.sim.scene_setup import cube_markers, load_scene_setup
from wristmark.sim.setup import _image_fill

TWO = CONFIG_DIR / "scenes" / "two_arms.yaml"


def test_the_shipped_scenes_load_with_their_arms_bases_and_markers() -> None:
    two = Scene.load(TWO)
    assert two.names == ["a", "b"]
    assert two.clearance == pytest.approx(0.003)
    assert np.allclose(two.arms[0].base, np.eye(4))
    assert np.allclose(two.arms[1].base[:3, 3], [0.2, 0.0, 0.0])
    assert np.allclose(two.arms[1].base[:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    three = Scene.load(CONFIG_DIR / "scenes" / "three_arms.yaml")
    assert three.names == ["a", "b", "c"]


def test_pose_from_xyz_rpy_is_rz_ry_rx() -> None:
    T = pose_from_xyz_rpy([1, 2, 3], [np.pi / 2, 0, 0])
    assert np.allclose(T[:3, :3] @ [0, 1, 0], [0, 0, 1])
    T = pose_from_xyz_rpy([0, 0, 0], [0.1, 0.2, 0.3])
    from scipy.spatial.transform import Rotation

    assert np.allclose(T[:3, :3], Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix())


def test_each_arm_sees_the_scene_camera_from_its_own_base_and_every_cube_is_in_view() -> None:
    s = load_scene_setup(TWO)
    W = np.asarray(s.camera.T_world_left, float)
    for name, arm in s.arms.items():
        assert np.allclose(s.base(name) @ np.asarray(arm.camera.T_world_left, float), W)
        pts = cube_markers(arm.params, s.scene.cube_size)
        scene_pts = pts @ s.base(name)[:3, :3].T + s.base(name)[:3, 3]
        assert _image_fill(s.camera, scene_pts, W) < 1.0  # inside the image
    # the two arms' cubes lie side by side, 45 mm apart between centres (no overlap)
    a = cube_markers(s.arms["a"].params, s.scene.cube_size).mean(0)
    b = cube_markers(s.arms["b"].params, s.scene.cube_size).mean(0)
    b_scene = s.base("b")[:3, :3] @ b + s.base("b")[:3, 3]
    assert abs(b_scene[0] - a[0]) > 0.04


def _scene(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    return p


A = str(CONFIG_DIR / "scenes" / "two_arms" / "a.yaml")
B = str(CONFIG_DIR / "scenes" / "two_arms" / "b.yaml")


@pytest.mark.parametrize(("text", "cause"), [
    ("arms: []", "'arms' must be a list"),
    (f"arms:\n  - marker: {A}\n  - marker: {A}\n", "the same arm name"),
    (f"arms:\n  - marker: {A}\n  - marker: {B}\nclearance: -1\n", "'clearance' must be in"),
    (f"arms:\n  - marker: {A}\n    base: {{xyz: [0, 0]}}\n", "'base.xyz' must be a list of 3"),
    (f"arms:\n  - marker: {A}\n    base: {{xyz: [0, 0, .nan]}}\n", "must be a finite number"),
    (f"arms:\n  - marker: {A}\n    colour: red\n", "unknown key 'colour'"),
    ("arms:\n  - marker: nowhere.yaml\n", "nowhere.yaml not found"),
    (f"arms:\n  - marker: {CONFIG_DIR / 'marker_coded.yaml'}\n", "must name it ('arm: NAME')"),
    (f"arms:\n  - marker: {A}\ncube_size: [0.02, 0.01]\n", "'cube_size' must be"),
    (f"arms:\n  - marker: {A}\ncamera_offset: 1\n", "unknown key 'camera_offset'"),
])
def test_bad_scenes_are_refused_in_one_line_naming_the_cause(tmp_path: Path, text: str, cause: str) -> None:
    with pytest.raises(ConfigError) as e:
        Scene.load(_scene(tmp_path, text))
    assert cause in str(e.value)
    assert "\n" not in str(e.value)


def test_two_markers_with_the_same_code_are_refused(tmp_path: Path) -> None:
    twin = tmp_path / "twin.yaml"
    twin.write_text(Path(A).read_text().replace("arm: a", "arm: twin"))
    with pytest.raises(ConfigError, match="the same code"):
        Scene.load(_scene(tmp_path, f"arms:\n  - marker: {A}\n  - marker: {twin}\n"))


def test_paths_are_relative_to_the_scene_file(tmp_path: Path) -> None:
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "a.yaml").write_text(Path(A).read_text())
    s = Scene.load(_scene(tmp_path, "arms:\n  - marker: m/a.yaml\n    robot: robots/planar.yaml\n"))
    assert s.arms[0].marker == tmp_path / "m" / "a.yaml"
    assert s.arms[0].robot is not None and s.arms[0].robot.name == "planar.yaml"
