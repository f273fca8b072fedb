"""The 3D scene of the bench in Meshcat: the arm from the generated URDF (through Pinocchio's
MeshcatVisualizer; models.urdf for the reference arm, models.arm_urdf for any arm of a format-2
robot file: its stem joints and 1 to 4 segments), its commanded configuration as a translucent ghost, the wrist marker's
checker sleeve, the stereo endoscope with both view frustums, the four tip spheres and their
trails. Frames: {w} world (the incision, z along the stem), {wm} marker; metres.

Scene tree (under ``/meshcat/wristmark``, shifted so the framed target is the orbit origin):
``arm/visuals/*`` true arm, ``ghost/visuals/*`` commanded arm, ``marker/{black,white}``,
``tips/<kind>``, ``trails/<kind>``, ``endoscope/{shaft,left_frustum,right/frustum}``,
``grid``, ``world_axes``. ``<kind>`` is one of style.TIP_KINDS.

One frame of the scene is a :class:`SceneState`; :meth:`ArmScene.node_poses` turns it into
node poses that a live view sends at once and a replay records as animation key frames.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.arm_pinocchio import PinocchioAnyArm
from wristmark.models.arm_shape import arm_shape
from wristmark.models.arm_spec import Arm, ArmSpec, home_psi
from wristmark.models.kinematics import check_psi, forward_kinematics
from wristmark.models.marker import MarkerModel
from wristmark.models.pinocchio_model import PinocchioArm
from wristmark.models.robot_params import RobotParams
from wristmark.models.urdf import MATERIALS
from wristmark.viz import shapes
from wristmark.viz.framing import CameraView, frame_points
from wristmark.viz.style import (
    BACKGROUND_BOTTOM,
    BACKGROUND_TOP,
    GHOST_COLOR,
    GHOST_OPACITY,
    GHOST_RADIUS_SCALE,
    GRID_COLOR,
    LEFT_FRUSTUM_COLOR,
    RIGHT_FRUSTUM_COLOR,
    TIP_KINDS,
    TIP_STYLES,
    TRAIL_OPACITY,
    TipStyle,
    hex_color,
)

if TYPE_CHECKING:
    from wristmark.rig.loop.loop_setup import LoopSetup
    from wristmark.rig.recording.run_log import CycleRecord
    from wristmark.viz.record_wire import WireRecord

Array = NDArray[np.float64]

ROOT = "wristmark"
HIDDEN_SCALE = 1e-6  # [-] scale of a node that has nothing to show (e.g. no vision estimate)
CAMERA_NODE = "/Cameras/default/rotated/<object>"


@dataclass(frozen=True)
class SceneConfig:
    """What the scene draws: the arm (the reference arm's RobotParams or any arm's ArmSpec) and
    marker geometry, the stereo endoscope (None: not drawn) and the true arm's stem coupling [-]
    (plant file), so psi_true draws the true arm exactly."""

    params: Arm = field(default_factory=RobotParams)
    marker: MarkerModel = field(default_factory=MarkerModel)
    camera: StereoCamera | None = None
    stem_coupling: float = 0.0
    links_per_segment: int = 6  # pseudo-rigid links drawn per segment

    @classmethod
    def from_setup(cls, setup: LoopSetup) -> SceneConfig:
        """The scene of a loop's setup; a simulated bench's (sim.setup.SimSetup) also gives the
        true arm's stem coupling (hardware: none known, 0)."""
        plant = getattr(setup, "plant", None)
        return cls(setup.params, setup.marker, setup.camera, float(getattr(plant, "stem_coupling", 0.0)))


@dataclass
class SceneState:
    """One frame: the true arm at ``psi_true`` (NaN: draw ``psi_cmd``), the ghost at
    ``psi_cmd`` and the tips in {w} [m] keyed by style.TIP_KINDS (None or NaN: hidden)."""

    psi_true: Array
    psi_cmd: Array
    tips: dict[str, Array | None]
    t: float = 0.0
    phase: str = ""

    @classmethod
    def from_record(cls, rec: CycleRecord | WireRecord) -> SceneState:
        """The frame of one servo cycle (as logged, or as the live view receives it)."""
        return cls(
            psi_true=np.asarray(rec.psi_true, float),
            psi_cmd=np.asarray(rec.psi_cmd, float),
            tips={"desired": rec.p_des, "commanded": rec.p_cmd, "estimated": rec.p_est, "true": rec.p_true},
            t=float(rec.t),
            phase=rec.phase,
        )

    @classmethod
    def at_rest(cls, params: Arm, psi: object = None) -> SceneState:
        """The arm resting at ``psi`` [rad, m] (None: its home) with the model's tip as
        desired/commanded/true."""
        q = check_psi(home_psi(params) if psi is None else psi, params)
        tip = forward_kinematics(params, q).tip
        return cls(q.copy(), q.copy(), {"desired": tip, "commanded": tip, "estimated": None, "true": tip})


def _finite(p: object) -> Array | None:
    if p is None:
        return None
    a = np.asarray(p, float).reshape(-1)
    return a if a.shape == (3,) and np.all(np.isfinite(a)) else None


def view_points(params: Arm, states: Iterable[SceneState], kinds: Iterable[str] = TIP_KINDS,
                max_states: int = 200) -> list[Array]:
    """Points [m, the arm's {w}] a view must show: the arm's centreline in (up to ``max_states``
    of) ``states`` and their finite tips of ``kinds``."""
    states = list(states)
    kinds = tuple(kinds)
    step = max(1, len(states) // max_states)
    pts: list[Array] = []
    for s in states[::step]:
        psi = s.psi_true if np.all(np.isfinite(s.psi_true)) else s.psi_cmd
        pts += list(arm_shape(params, psi, 6).centreline)
    for s in states:
        pts += [p for p in (_finite(s.tips.get(k)) for k in kinds) if p is not None]
    return pts


class _ArmNodes:
    """One arm (true or ghost) drawn from the URDF's visuals through Pinocchio's visualizer."""

    def __init__(self, vis: meshcat.Visualizer, arm: PinocchioArm | PinocchioAnyArm, root: str, drop_sleeve: bool,
                 color: list[float] | None, radius_scale: float) -> None:
        from pinocchio.visualize import MeshcatVisualizer

        self.arm = arm
        sleeve = np.array(MATERIALS["sleeve"])
        gm = pin.GeometryModel()
        for g in arm.visual_model.geometryObjects:
            is_sleeve = arm.model.frames[g.parentFrame].name == "marker" and np.allclose(g.meshColor, sleeve)
            if not (drop_sleeve and is_sleeve):
                gm.addGeometryObject(g)
        self.geometry = gm
        self.geometry_data = gm.createData()
        self.viz = MeshcatVisualizer(arm.model, None, gm)
        self.viz.initViewer(viewer=vis)
        self.viz.loadViewerModel(rootNodeName=root, visual_color=color)
        self.paths = [f"{root}/visuals/{g.name}" for g in gm.geometryObjects]
        self.scale = np.diag([radius_scale, radius_scale, 1.0, 1.0])  # URDF cylinders lie along z

    def poses(self, psi: Array, correction: Array | None = None) -> list[tuple[str, Array]]:
        """(node path, 4x4 pose in {w}) of every visual at psi; ``correction`` premultiplies."""
        q = self.arm.q_from_psi(psi)
        pin.forwardKinematics(self.arm.model, self.arm.data, q)
        pin.updateGeometryPlacements(self.arm.model, self.arm.data, self.geometry, self.geometry_data)
        out = []
        for path, M in zip(self.paths, self.geometry_data.oMg):
            T = M.homogeneous @ self.scale
            out.append((path, T if correction is None else correction @ T))
        return out


def _pinocchio_arm(cfg: SceneConfig) -> PinocchioArm | PinocchioAnyArm:
    """The pseudo-rigid Pinocchio model that draws ``cfg``'s arm (its URDF's visuals)."""
    if isinstance(cfg.params, ArmSpec):
        return PinocchioAnyArm(cfg.params, cfg.links_per_segment, cfg.marker)
    return PinocchioArm(cfg.params, cfg.links_per_segment, cfg.marker)


def build_stage(vis: meshcat.Visualizer, view: CameraView, camera: StereoCamera | None) -> None:
    """What every scene shares: a cleared root, the background, the browser's camera, the floor
    grid, the {w} triad, and the stereo endoscope (``camera``'s world_T_left; None: not drawn)."""
    vis[ROOT].delete()
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    vis["/Background"].set_property("top_color", list(BACKGROUND_TOP))
    vis["/Background"].set_property("bottom_color", list(BACKGROUND_BOTTOM))
    set_view(vis, view)
    vis[f"{ROOT}/grid"].set_object(shapes.line_segments(shapes.floor_grid(), GRID_COLOR, 1.0))
    vis[f"{ROOT}/world_axes"].set_object(mg.triad(0.01))


def build_endoscope(vis: meshcat.Visualizer, cam: StereoCamera | None) -> None:
    """The endoscope's shaft and both view frustums at ``cam``'s world_T_left (none: nothing)."""
    if cam is None or cam.T_world_left is None:
        return
    vis[f"{ROOT}/endoscope"].set_transform(np.asarray(cam.T_world_left, float))
    geom, mat, T = shapes.endoscope_shaft()
    c_right = -np.asarray(cam.R, float).T @ np.asarray(cam.T, float)  # right centre in {ll}
    vis[f"{ROOT}/endoscope/shaft"].set_object(geom, mat)
    vis[f"{ROOT}/endoscope/shaft"].set_transform(shapes.translation(c_right / 2.0) @ T)
    vis[f"{ROOT}/endoscope/left_frustum"].set_object(
        shapes.line_segments(shapes.frustum_lines(cam.left.K, cam.image_size), LEFT_FRUSTUM_COLOR))
    T_left_right = np.linalg.inv(np.asarray(cam.T_world_left, float)) @ shapes.world_T_right(cam)
    vis[f"{ROOT}/endoscope/right"].set_transform(T_left_right)
    vis[f"{ROOT}/endoscope/right/frustum"].set_object(
        shapes.line_segments(shapes.frustum_lines(cam.right.K, cam.image_size), RIGHT_FRUSTUM_COLOR))


def set_view(vis: meshcat.Visualizer, view: CameraView) -> None:
    """Point the browser's camera: shift the scene so ``view.target`` is the orbit origin."""
    vis[ROOT].set_transform(view.scene_shift())
    vis[CAMERA_NODE].set_property("position", view.threejs_position())


class ArmScene:
    """Builds the scene in a Meshcat visualizer and computes the node poses of each frame (in {w},
    [m]).

    By default the whole scene of one arm. With ``stage=False`` only the arm's own nodes under
    ``root`` (its body, marker, tips and trails; ``ghost``: also the commanded arm; ``tips``: the
    tip kinds drawn and their styles, default style.TIP_STYLES), positions in the arm's {w}: a
    part of a scene of several arms (viz.arms_scene)."""

    def __init__(self, vis: meshcat.Visualizer, config: SceneConfig | None = None,
                 view: CameraView | None = None, *, root: str = ROOT, stage: bool = True, ghost: bool = True,
                 tips: Mapping[str, TipStyle] | None = None) -> None:
        self.vis = vis
        self.config = config if config is not None else SceneConfig()
        self.root = root
        self.tip_styles = dict(TIP_STYLES if tips is None else tips)
        self.tip_kinds = tuple(self.tip_styles)
        cfg = self.config
        self._true_arm = _pinocchio_arm(cfg)
        self._ghost_arm = _pinocchio_arm(cfg) if ghost else None
        self.view = view if view is not None else self.frame_on([SceneState.at_rest(cfg.params)])
        self._build(stage)

    # -- construction ------------------------------------------------------------------------
    def _build(self, stage: bool) -> None:
        vis, cfg, root = self.vis, self.config, self.root
        if stage:
            build_stage(vis, self.view, cfg.camera)
        self._arm = _ArmNodes(vis, self._true_arm, f"{root}/arm", drop_sleeve=True, color=None, radius_scale=1.0)
        self._ghost = None if self._ghost_arm is None else _ArmNodes(
            vis, self._ghost_arm, f"{root}/ghost", drop_sleeve=False, color=[*GHOST_COLOR, GHOST_OPACITY],
            radius_scale=GHOST_RADIUS_SCALE)
        black, white = shapes.checker_sleeve(cfg.marker)
        mat_black, mat_white = shapes.sleeve_materials()
        vis[f"{root}/marker/black"].set_object(black, mat_black)
        vis[f"{root}/marker/white"].set_object(white, mat_white)
        for kind, st in self.tip_styles.items():
            # Drawn in the transparent pass without depth test: always visible, even inside the
            # gripper or behind the arm (the true tip is at the jaws' end).
            mat = mg.MeshPhongMaterial(color=hex_color(st.color), opacity=st.opacity, transparent=True,
                                       reflectivity=0.2, depthTest=False)
            vis[f"{root}/tips/{kind}"].set_object(mg.Sphere(st.radius), mat)
        if stage:
            build_endoscope(vis, cfg.camera)

    def set_view(self, view: CameraView) -> None:
        """Point the browser's camera: shift the scene so ``view.target`` is the orbit origin."""
        self.view = view
        set_view(self.vis, view)

    def frame_on(self, states: Iterable[SceneState], max_states: int = 200) -> CameraView:
        """A view framed on the arm of (up to ``max_states`` of) ``states``, their tips, the
        incision and the endoscope's lenses."""
        pts = [np.zeros(3), *view_points(self.config.params, states, self.tip_kinds, max_states)]
        cam = self.config.camera
        if cam is not None and cam.T_world_left is not None:
            pts.append(np.asarray(cam.T_world_left, float)[:3, 3])
        return frame_points(np.array(pts))

    # -- frames ------------------------------------------------------------------------------
    def _stem_bend(self, psi: Array) -> float:
        """Bend [rad] of the exposed stem: stem_coupling x theta1 (the first segment's bend), as
        the simulated true arm."""
        arm = self.config.params
        i = arm.theta_index[0] if isinstance(arm, ArmSpec) else 2
        return float(self.config.stem_coupling * psi[i])

    def stem_correction(self, psi: Array) -> Array:
        """Pose change of {1b} (and all that follows) when the exposed stem (length d) bends by
        stem_coupling * theta1 in segment 1's plane, as the simulated true arm does (both from
        the model's chain, models.kinematics)."""
        if self.config.stem_coupling == 0.0:
            return np.eye(4)
        params = self.config.params
        bent = forward_kinematics(params, psi, stem_bend=self._stem_bend(psi)).T_world_1b
        return np.asarray(bent @ np.linalg.inv(forward_kinematics(params, psi).T_world_1b))

    def node_poses(self, state: SceneState) -> list[tuple[str, Array]]:
        """(node path relative to /meshcat, 4x4 pose in {w}) of every moving node at ``state``;
        hidden tips get a vanishing scale."""
        psi_cmd = check_psi(state.psi_cmd, self.config.params)
        psi_true = np.asarray(state.psi_true, float)
        if psi_true.shape == psi_cmd.shape and np.all(np.isfinite(psi_true)):
            C, stem_bend = self.stem_correction(psi_true), self._stem_bend(psi_true)
        else:  # true configuration unknown (hardware, accuracy runs): the arm as commanded
            psi_true, C, stem_bend = psi_cmd, np.eye(4), 0.0
        poses = self._arm.poses(psi_true, C)
        if self._ghost is not None:
            poses += self._ghost.poses(psi_cmd)
        poses.append((f"{self.root}/marker",
                      forward_kinematics(self.config.params, psi_true, stem_bend).T_world_marker))
        for kind in self.tip_kinds:
            p = _finite(state.tips.get(kind))
            T = np.eye(4)
            if p is None:
                T[:3, :3] *= HIDDEN_SCALE
            else:
                T[:3, 3] = p
            poses.append((f"{self.root}/tips/{kind}", T))
        return poses

    def show(self, state: SceneState) -> None:
        """Send the poses of ``state`` to the visualizer (one set_transform per node)."""
        for path, T in self.node_poses(state):
            self.vis[path].set_transform(T)

    def set_trails(self, trails: Mapping[str, Array], opacity: float = TRAIL_OPACITY) -> None:
        """Replace the trail lines: (N, 3) points in {w} [m] per tip kind (missing: cleared)."""
        for kind in self.tip_kinds:
            P = np.asarray(trails.get(kind, np.zeros((0, 3))), float).reshape(-1, 3)
            P = P[np.all(np.isfinite(P), axis=1)]
            node = self.vis[f"{self.root}/trails/{kind}"]
            if len(P) < 2:
                node.delete()
            else:
                node.set_object(shapes.polyline(P, self.tip_styles[kind].color, opacity))
