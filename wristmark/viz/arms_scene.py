"""The 3D scene of several arms in one endoscope view (sim.scene): every arm at its base pose in
the scene's world frame {w}, each with its body, marker, desired, vision-estimated and true tips
and their trails in its own colour (style.arm_tip_styles), a label naming it, and the one
endoscope. Frames: the scene's {w}; each arm's nodes sit under its base node, in its own {w}
(where its robot file puts it and its log's positions are); metres.

Scene tree (under ``/meshcat/wristmark``): ``arms/<name>`` (transform: the arm's base pose) with
``arm/visuals/*``, ``marker/{black,white}``, ``tips/<kind>``, ``trails/<kind>[/<phase>]`` and
``label`` below it; ``endoscope/...``, ``grid``, ``world_axes`` as in the one-arm scene
(viz.scene). ``<kind>`` is one of style.ARM_TIP_KINDS.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import cv2
import meshcat
import meshcat.geometry as mg
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.viz.framing import DEFAULT_DIRECTION, CameraView, frame_points
from wristmark.viz.scene import ROOT, ArmScene, SceneConfig, SceneState, build_endoscope, build_stage, view_points
from wristmark.viz.scene import set_view as point_camera
from wristmark.viz.style import ARM_TIP_KINDS, RGB, arm_color, arm_tip_styles

Array = NDArray[np.float64]


class ArmsSetup(Protocol):
    """What the view needs of a setup of several arms (sim.scene_setup.SceneSetup): each arm's
    loop setup (rig.loop.loop_setup.LoopSetup, by name, in order), its base pose and the camera."""

    @property
    def arms(self) -> Mapping[str, Any]:
        """Each arm's loop setup by name, in order."""

    @property
    def camera(self) -> StereoCamera:
        """The scene camera (``world_T_left`` in the scene's {w})."""

    @property
    def names(self) -> list[str]:
        """The arms' names, in order."""

    def base(self, name: str) -> Array:
        """Pose of arm ``name``'s {w} in the scene's {w} (4x4, [m])."""

LABEL_HEIGHT = 0.01  # [m] of an arm's name tag
LABEL_LIFT = 0.012  # [m] the tag sits this far above the arm's tip at home (along the scene's z)


def arm_root(name: str) -> str:
    """The scene-tree node of arm ``name`` (relative to /meshcat)."""
    return f"{ROOT}/arms/{name}"


@dataclass(frozen=True)
class ArmsSceneConfig:
    """What a scene of several arms draws: per arm (in the scene file's order) its one-arm scene
    configuration (no camera: the scene's is drawn once) and its base pose (4x4, its {w} in the
    scene's {w} [m]), and the scene camera (``world_T_left`` in the scene's {w}; None: not drawn)."""

    arms: dict[str, SceneConfig]
    bases: dict[str, Array]
    camera: StereoCamera | None = None

    @property
    def names(self) -> list[str]:
        """The arms' names, in order."""
        return list(self.arms)

    def color(self, name: str) -> RGB:
        """Arm ``name``'s colour (style.arm_color of its place in the scene)."""
        return arm_color(self.names.index(name))

    @classmethod
    def from_scene_setup(cls, setup: ArmsSetup) -> ArmsSceneConfig:
        """The scene of a run of several arms (sim.scene_setup.SceneSetup)."""
        arms = {n: dataclasses.replace(SceneConfig.from_setup(s), camera=None) for n, s in setup.arms.items()}
        return cls(arms, {n: np.asarray(setup.base(n), float) for n in setup.names}, setup.camera)


def label_png(text: str, rgb: RGB) -> tuple[bytes, tuple[int, int]]:
    """PNG of a name tag: ``text`` in colour ``rgb`` on white, framed in the same colour; and
    its (width, height) [px]."""
    bgr = tuple(int(round(255 * c)) for c in reversed(rgb))
    scale, thick = 1.6, 3
    (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    pad = 12
    img = np.full((h + base + 2 * pad, w + 2 * pad, 3), 255, np.uint8)
    cv2.putText(img, text, (pad, pad + h), cv2.FONT_HERSHEY_SIMPLEX, scale, bgr, thick, cv2.LINE_AA)
    cv2.rectangle(img, (2, 2), (img.shape[1] - 3, img.shape[0] - 3), bgr, 4)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise ValueError(f"cannot encode the label of '{text}'")
    return buf.tobytes(), (img.shape[1], img.shape[0])


def label_pose(point: Array, direction: Iterable[float] = DEFAULT_DIRECTION) -> Array:
    """4x4 pose in {w} of a tag at ``point`` [m] facing the viewer who looks from ``direction``
    (+z towards the viewer, +y up on the screen)."""
    d = np.asarray(list(direction), float)
    d /= np.linalg.norm(d)
    right = np.cross(-d, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -d)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([right, up, d])
    T[:3, 3] = point
    return T


class ArmsScene:
    """Builds the scene of several arms and computes the node poses of each frame."""

    def __init__(self, vis: meshcat.Visualizer, config: ArmsSceneConfig, view: CameraView | None = None) -> None:
        self.vis = vis
        self.config = config
        rest = {n: SceneState.at_rest(c.params) for n, c in config.arms.items()}
        self.view = view if view is not None else self.frame_on({n: [s] for n, s in rest.items()})
        build_stage(vis, self.view, config.camera)
        self.parts: dict[str, ArmScene] = {}
        for i, name in enumerate(config.names):
            root = arm_root(name)
            vis[root].set_transform(config.bases[name])
            self.parts[name] = ArmScene(vis, config.arms[name], self.view, root=root, stage=False, ghost=False,
                                        tips=arm_tip_styles(arm_color(i)))
            self._label(name, rest[name])
        build_endoscope(vis, config.camera)

    def _label(self, name: str, rest: SceneState) -> None:
        """The arm's name tag above its tip at home, facing the default view."""
        B = self.config.bases[name]
        tip = B[:3, :3] @ np.asarray(rest.tips["true"], float) + B[:3, 3]
        T = np.linalg.inv(B) @ label_pose(tip + [0.0, 0.0, LABEL_LIFT])
        png, (w, h) = label_png(name, self.config.color(name))
        node = self.vis[f"{arm_root(name)}/label"]
        node.set_object(mg.Box([LABEL_HEIGHT * w / h, LABEL_HEIGHT, 1e-5]),
                        mg.MeshBasicMaterial(map=mg.ImageTexture(image=mg.PngImage(png))))
        node.set_transform(T)

    def set_view(self, view: CameraView) -> None:
        """Point the browser's camera (viz.scene.set_view)."""
        self.view = view
        point_camera(self.vis, view)

    def frame_on(self, states: Mapping[str, Iterable[SceneState]], max_states: int = 200) -> CameraView:
        """A view framed on every arm in (up to ``max_states`` of) its ``states``, their tips, the
        arms' incisions and the endoscope's lenses (all in the scene's {w})."""
        pts: list[Array] = []
        for name, sts in states.items():
            B = self.config.bases[name]
            P = np.array([np.zeros(3), *view_points(self.config.arms[name].params, sts, ARM_TIP_KINDS, max_states)])
            pts += list(P @ B[:3, :3].T + B[:3, 3])
        cam = self.config.camera
        if cam is not None and cam.T_world_left is not None:
            pts.append(np.asarray(cam.T_world_left, float)[:3, 3])
        return frame_points(np.array(pts))

    def node_poses(self, states: Mapping[str, SceneState]) -> list[tuple[str, Array]]:
        """(node path, 4x4 pose in its arm's {w}) of every moving node of the arms in ``states``."""
        out: list[tuple[str, Array]] = []
        for name, state in states.items():
            out += self.parts[name].node_poses(state)
        return out

    def show(self, states: Mapping[str, SceneState]) -> None:
        """Send the poses of ``states`` (one set_transform per node)."""
        for path, T in self.node_poses(states):
            self.vis[path].set_transform(T)
