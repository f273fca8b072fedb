"""The scene of several arms (viz.arms_scene) without a browser: every arm under its base pose
with its body, marker, tips and name tag; poses in each arm's own {w}; colours per arm."""

from __future__ import annotations

import numpy as np
import umsgpack

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.kinematics import forward_kinematics
from wristmark.sim.scene_setup import load_scene_setup
from wristmark.viz import command_tree
from wristmark.viz.arms_scene import ArmsScene, ArmsSceneConfig, arm_root, label_pose
from wristmark.viz.framing import DEFAULT_DIRECTION
from wristmark.viz.scene import ROOT, SceneState
from wristmark.viz.snapshot import recording_visualizer
from wristmark.viz.style import ARM_TIP_KINDS, arm_color, arm_tip_styles, arms_legend

TWO_ARMS = CONFIG_DIR / "scenes" / "two_arms.yaml"


def node(window: object, path: str) -> object:
    """The recorded scene tree's node at ``path`` (below /meshcat)."""
    return command_tree.find_node(window.tree, ["meshcat", *path.split("/")])  # type: ignore[attr-defined]


def transform_of(window: object, path: str) -> np.ndarray:
    """The 4x4 transform last set on ``path`` in the recorded scene."""
    data = umsgpack.unpackb(node(window, path).transform)  # type: ignore[attr-defined]
    return np.asarray(data["matrix"], float).reshape(4, 4).T


def test_every_arm_is_drawn_under_its_base_pose_with_its_own_nodes() -> None:
    setup = load_scene_setup(TWO_ARMS)
    config = ArmsSceneConfig.from_scene_setup(setup)
    assert config.names == ["a", "b"] and config.camera is not None
    assert all(c.camera is None for c in config.arms.values())  # the endoscope is drawn once
    vis, window = recording_visualizer()
    scene = ArmsScene(vis, config)
    for name in ("a", "b"):
        np.testing.assert_allclose(transform_of(window, arm_root(name)), setup.base(name), atol=1e-12)
        for kind in ARM_TIP_KINDS:
            assert node(window, f"{arm_root(name)}/tips/{kind}").object is not None  # type: ignore[attr-defined]
        assert node(window, f"{arm_root(name)}/label").object is not None  # type: ignore[attr-defined]
        assert node(window, f"{arm_root(name)}/marker/black").object is not None  # type: ignore[attr-defined]
        assert "ghost" not in node(window, arm_root(name))  # type: ignore[operator]
    assert node(window, f"{ROOT}/endoscope/left_frustum").object is not None  # type: ignore[attr-defined]
    np.testing.assert_allclose(transform_of(window, f"{ROOT}/endoscope"), setup.camera.T_world_left, atol=1e-12)
    # the view shows both arms: b's base (200 mm along x) and a's are inside the framed sphere
    assert scene.view.distance > 0.15 and 0.05 < scene.view.target[0] < 0.15


def test_node_poses_are_in_each_arms_own_frame() -> None:
    setup = load_scene_setup(TWO_ARMS)
    vis, _ = recording_visualizer()
    scene = ArmsScene(vis, ArmsSceneConfig.from_scene_setup(setup))
    states = {}
    for i, name in enumerate(("a", "b")):
        p = setup.arms[name].params
        psi = SceneState.at_rest(p).psi_cmd + 0.05 * (i + 1)
        tip = forward_kinematics(p, psi).tip
        states[name] = SceneState(psi, psi, {"desired": tip + 0.001, "estimated": tip - 0.001, "true": tip,
                                             "commanded": tip})
    poses = dict(scene.node_poses(states))
    for name in ("a", "b"):
        np.testing.assert_allclose(poses[f"{arm_root(name)}/tips/desired"][:3, 3], states[name].tips["desired"])
        np.testing.assert_allclose(poses[f"{arm_root(name)}/tips/estimated"][:3, 3], states[name].tips["estimated"])
        assert f"{arm_root(name)}/tips/commanded" not in poses  # several arms: desired, estimated, true only
        assert any(p.startswith(f"{arm_root(name)}/arm/visuals/seg2_link_") for p in poses)
    # only the arms given move
    assert not any(p.startswith(arm_root("b")) for p, _ in scene.node_poses({"a": states["a"]}))


def test_each_arm_has_its_colour_in_the_tips_and_the_legend() -> None:
    a, b = arm_tip_styles(arm_color(0)), arm_tip_styles(arm_color(1))
    assert arm_color(0) != arm_color(1)
    assert a["estimated"].color == arm_color(0) and b["estimated"].color == arm_color(1)
    for st in (a, b):  # desired lighter, true darker than the arm's colour
        assert sum(st["desired"].color) > sum(st["estimated"].color) > sum(st["true"].color)
    rows = arms_legend(["left", "right"])
    assert rows[0][0].startswith("arm left") and rows[1][0].startswith("arm right")
    assert rows[0][1] == tuple(a[k].color for k in ARM_TIP_KINDS)


def test_name_tag_faces_the_default_view() -> None:
    T = label_pose(np.array([0.1, 0.0, 0.15]))
    d = np.asarray(DEFAULT_DIRECTION) / np.linalg.norm(DEFAULT_DIRECTION)
    np.testing.assert_allclose(T[:3, 2], d, atol=1e-12)  # +z towards the viewer
    assert T[2, 1] > 0.5  # +y up on the screen
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
