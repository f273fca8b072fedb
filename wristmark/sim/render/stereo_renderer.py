"""Stereo image synthesis of the marked arm: :class:`StereoRenderer` -> :class:`RenderedPair`,
or of several arms at once -> :class:`RenderedScene`.

Each camera sees the same world: the distal arm (tube along the true centreline, rigid link,
checkered marker sleeve, gripper) ray-cast through the camera's exact distortion at
``settings.supersampling`` samples per pixel axis over a cached tissue background, then the
optics of :mod:`sim.render.optics` and the sensor of :mod:`sim.render.sensor`. Ground truth
(pose of {wm} in {ll}, tip in {ll}, raw pixel corners with their cos_view per camera) follows
docs/design.md's truth.json.

Several arms (a renderer built with one marker per arm, :meth:`StereoRenderer.render_arms`)
are ray-cast together, each with its own sleeve: every ray keeps its nearest hit, so the arms
hide one another where they cross, and each corner's truth says whether another arm's body
hides it in that camera (``CornerTruth.occluded``).

Only what changes is rendered: the optics of the background are computed once per renderer;
each frame ray-casts the arms' tiles into a radiance buffer holding the background, blurs only
the arms' tile rows (each row's span of tiles grown by the blur's reach) into a signal buffer
holding the background's optics, draws fresh sensor noise over the whole frame straight into
the output image (one side-by-side buffer for :meth:`StereoRenderer.render_side_by_side`), then
puts the background back where the arm was. With motion blur (a new direction every frame) the
optics run over the whole frame instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.arm_shape import ArmShape
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.arm import (
    METAL,
    TUBE,
    ArmPlan,
    Box,
    Capsule,
    Sleeve,
    glossy_materials,
    hidden_points,
    plan_arm,
    ray_map,
    render_arm,
)
from wristmark.sim.render.background import seeded_stereo_backgrounds
from wristmark.sim.render.optics import blur_radius, grow_box, optics_signal, optics_signal_box, vignetting_map
from wristmark.sim.render.raycast import TILE
from wristmark.sim.render.sensor import sensor_image
from wristmark.sim.render.settings import RenderSettings

Array = NDArray[np.float64]
EXPOSURE = 200.0  # grey levels for unit radiance (white patch facing the light at D0)
GRIPPER_RADIUS = 0.0016  # [m]
JAW_RADIUS = 0.0006  # [m]


@dataclass(frozen=True)
class CornerTruth:
    """One marker corner in one camera: raw pixel uv [px] and cos_view (<= 0: facing away);
    ``occluded``: another arm of the scene is in front of it (always False with one arm)."""

    index: int
    uv: tuple[float, float]
    cos_view: float
    occluded: bool = False


@dataclass(frozen=True)
class RenderedPair:
    """A rendered stereo pair and its ground truth (left camera frame {ll}, metres).

    left, right: uint8 images (BGR (h, w, 3), or (h, w) if grayscale), as cv2.imread reads them.
    T_left_marker: 4x4 pose of {wm} in {ll}; tip_left: tip in {ll} [m].
    """

    left: NDArray[np.uint8]
    right: NDArray[np.uint8]
    T_left_marker: Array
    tip_left: Array
    corners_left: tuple[CornerTruth, ...]
    corners_right: tuple[CornerTruth, ...]


@dataclass(frozen=True)
class ArmTruth:
    """Ground truth of one arm of a scene (left camera frame {ll}, metres): pose of its {wm} in
    {ll}, its tip in {ll} [m] and its corners in each camera."""

    T_left_marker: Array
    tip_left: Array
    corners_left: tuple[CornerTruth, ...]
    corners_right: tuple[CornerTruth, ...]


@dataclass(frozen=True)
class RenderedScene:
    """A rendered stereo pair of several arms: images as in :class:`RenderedPair`, and ``arms``,
    one :class:`ArmTruth` per arm in the order of the renderer's markers."""

    left: NDArray[np.uint8]
    right: NDArray[np.uint8]
    arms: tuple[ArmTruth, ...]


def corner_truth(
    camera: Camera,
    marker: MarkerModel,
    T_cam_marker: Array,
    occluders: tuple[list[Capsule], list[Sleeve]] | None = None,
) -> tuple[CornerTruth, ...]:
    """Raw pixels and cos_view of every marker corner for a camera seeing {wm} at T_cam_marker;
    ``occluders``: other arms' capsules and sleeves in that camera's frame, which set
    ``occluded`` on the corners they hide (None: none)."""
    R, t = T_cam_marker[:3, :3], T_cam_marker[:3, 3]
    P = marker.corners() @ R.T + t
    N = marker.corner_normals() @ R.T
    uv = camera.project(P)
    cos = -(N * P).sum(axis=1) / np.linalg.norm(P, axis=1)
    hid = np.zeros(len(P), bool) if occluders is None else hidden_points(P, *occluders)
    return tuple(CornerTruth(i, (float(uv[i, 0]), float(uv[i, 1])), float(cos[i]), bool(hid[i]))
                 for i in range(marker.columns))


def arm_primitives(shape: ArmShape, marker: MarkerModel, T_cam_world: Array) -> tuple[list[Capsule], Sleeve]:
    """The arm's capsules and marker sleeve in a camera frame given the pose of {w} in it."""
    Rc, tc = T_cam_world[:3, :3], T_cam_world[:3, 3]

    def cam(p: Array) -> Array:
        return np.asarray(p, float) @ Rc.T + tc

    C = cam(shape.centreline)
    last = len(C) - 2
    caps = [Capsule(C[i], C[i + 1], shape.radius, TUBE, (True, i == last)) for i in range(len(C) - 1)]
    T_cm = T_cam_world @ shape.T_world_marker
    z, x, o = T_cm[:3, 2], T_cm[:3, 0], T_cm[:3, 3]
    z_lo, z_hi = marker.z_extent
    end = cam(shape.frames.T_world_2e[:3, 3])
    caps.append(Capsule(end, o + 0.5 * z_lo * z, shape.radius, METAL))  # rigid link into the sleeve
    tip = cam(shape.tip)
    base = tip - 0.0045 * z
    caps.append(Capsule(o + z_hi * z, base, GRIPPER_RADIUS, METAL))
    for sgn in (1.0, -1.0):  # two jaws, slightly open
        caps.append(Capsule(base + sgn * 0.0008 * x, tip + sgn * 0.0012 * x, JAW_RADIUS, METAL))
    return caps, Sleeve(T_cm, marker)


class StereoRenderer:
    """Renders the arm in a calibrated stereo endoscope (needs ``camera.T_world_left``), or
    several arms: ``marker`` is one marker model, or a sequence of them, one per arm (the
    shapes given to :meth:`render_arms` come in the same order).

    Deterministic per ``seed``: the background is drawn once; the k-th call of :meth:`render`
    (or :meth:`render_arms`) uses noise stream (seed, k).
    """

    def __init__(
        self, camera: StereoCamera, marker: MarkerModel | Sequence[MarkerModel], settings: RenderSettings,
        seed: int = 0,
    ) -> None:
        markers = (marker,) if isinstance(marker, MarkerModel) else tuple(marker)
        if not markers:
            raise InputError("the renderer needs at least one marker (one per arm)")
        camera.validate()
        for m in markers:
            m.validate()
        settings.validate()
        if camera.T_world_left is None:
            raise InputError("the calibration has no 'world_T_left': add it to render the arm in {w}")
        self.camera, self.settings, self.seed = camera, settings, int(seed)
        self.markers: tuple[MarkerModel, ...] = markers
        self.marker = markers[0]
        self._count = 0
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="render-right")
        right_map = self._pool.submit(ray_map, camera.right, camera.image_size)  # OpenCV releases the GIL
        self._maps = (ray_map(camera.left, camera.image_size), right_map.result())
        disparity = float(camera.left.K[0, 0]) * camera.baseline / 0.12  # tissue ~120 mm away
        self._bg = seeded_stereo_backgrounds(self.seed, camera.image_size, disparity, EXPOSURE * 0.9)
        vig = vignetting_map(camera.image_size, settings.vignetting)
        self._vignette: NDArray[np.float32] = np.asarray(cv2.merge([vig] * 3), np.float32)
        # the background's optics, once (None: motion blur changes them every frame)
        self._bg_signal = (
            None
            if settings.motion_blur > 0
            else tuple(optics_signal(bg, self._vignette, settings) for bg in self._bg)
        )
        # per camera, reused every frame: the radiance (the background, the arm ray-cast into it)
        # and the signal (the background's optics, the arm's written into it); restored after each
        self._rad = tuple(bg.copy() for bg in self._bg)
        self._sig = () if self._bg_signal is None else tuple(sig.copy() for sig in self._bg_signal)
        W = np.asarray(camera.T_world_left, float)
        self.T_left_world = np.linalg.inv(W)
        T_right_left = np.eye(4)
        T_right_left[:3, :3], T_right_left[:3, 3] = camera.R, camera.T
        self.T_right_world = T_right_left @ self.T_left_world
        self._mats = (self._glossy(np.eye(4)), self._glossy(T_right_left))

    def _glossy(self, T_cam_left: Array) -> Array | None:
        """The kernels' material rows for the camera at ``T_cam_left`` (pose of {ll} in it): the
        sleeve's laminate lit by the light outputs beside both lenses (None: the matte sleeve)."""
        st = self.settings
        if st.sleeve_specular <= 0 or st.shading != "phong":
            return None
        R, T = np.asarray(self.camera.R, float), np.asarray(self.camera.T, float).reshape(3)
        c_right = -R.T @ T  # the right lens's centre in {ll}
        y = np.array([0.0, 1.0, 0.0])
        offs = [0.0] if st.light_offset == 0 else [st.light_offset, -st.light_offset]
        pts = np.array([c + o * y for c in (np.zeros(3), c_right) for o in offs])
        pts = pts @ T_cam_left[:3, :3].T + T_cam_left[:3, 3]
        lights = np.column_stack([pts, np.full(len(pts), 1.0 / len(pts))])
        return glossy_materials(st.sleeve_specular, st.sleeve_roughness, lights)

    def _row_boxes(self, plan: ArmPlan) -> list[Box]:
        """Pixel boxes (u0, v0, u1, v1) of the plan's tile rows, each from its first to its last
        tile (within the image): the only pixels the ray casting changes."""
        w, h = self.camera.image_size
        js, is_ = plan.tiles[:, 0], plan.tiles[:, 1]
        boxes = []
        for j in np.unique(js):
            row = is_[js == j]
            boxes.append((int(row.min()) * TILE, int(j) * TILE, min(w, (int(row.max()) + 1) * TILE),
                          min(h, (int(j) + 1) * TILE)))
        return boxes

    def _shapes(self, shapes: ArmShape | Sequence[ArmShape]) -> tuple[ArmShape, ...]:
        """The arm shapes as a tuple, one per marker (else InputError)."""
        out = (shapes,) if isinstance(shapes, ArmShape) else tuple(shapes)
        if len(out) != len(self.markers):
            raise InputError(f"{len(out)} arm shape(s) for {len(self.markers)} marker(s): give one shape per marker")
        return out

    def _primitives(self, shapes: tuple[ArmShape, ...], T_cam_world: Array) -> list[tuple[list[Capsule], Sleeve]]:
        """Each arm's capsules and sleeve in the camera frame given the pose of {w} in it."""
        return [arm_primitives(shape, m, T_cam_world) for shape, m in zip(shapes, self.markers)]

    def _arm_signal(self, cam: int, shapes: tuple[ArmShape, ...], angle: float, incremental: bool) -> tuple[
            NDArray[np.float32], list[Box]]:
        """Sensor signal of one camera (0 left, 1 right) before noise [grey levels] and the boxes
        to restore afterwards with :meth:`_restore`: incrementally, the camera's signal buffer
        (the cached background's optics with those of the arms' tile rows written in); else (or
        with motion blur) a new whole-frame signal and no boxes."""
        T_cw = (self.T_left_world, self.T_right_world)[cam]
        rmap, st = self._maps[cam], self.settings
        prims = self._primitives(shapes, T_cw)
        caps = [c for cs, _ in prims for c in cs]
        plan = plan_arm(rmap, caps, [s for _, s in prims], st.supersampling, st.arm_supersampling)
        flat = st.shading == "flat"
        if incremental and self._bg_signal is not None:
            sig = self._sig[cam]
            if plan is None:
                return sig, []
            rad, size, r = self._rad[cam], self.camera.image_size, blur_radius(st)
            boxes = self._row_boxes(plan)
            try:
                render_arm(rmap, plan, EXPOSURE, rad, (0, 0), flat, st.adaptive_supersampling, self._mats[cam])
                for b in boxes:  # each row's optics from the radiance around it (arm rows above and below included)
                    outer = grow_box(b, 2 * r, size)
                    patch, (u0, v0) = optics_signal_box(rad[outer[1] : outer[3], outer[0] : outer[2]],
                                                        (outer[0], outer[1]), b, self._vignette, st)
                    sig[v0 : v0 + patch.shape[0], u0 : u0 + patch.shape[1]] = patch
            finally:
                bg = self._bg[cam]
                for u0, v0, u1, v1 in boxes:
                    rad[v0:v1, u0:u1] = bg[v0:v1, u0:u1]
            return sig, [grow_box(b, r, size) for b in boxes]
        img = self._bg[cam].copy()
        if plan is not None:
            render_arm(rmap, plan, EXPOSURE, img, (0, 0), flat, st.adaptive_supersampling, self._mats[cam])
        return optics_signal(img, self._vignette, st, angle), []

    def _restore(self, cam: int, boxes: list[Box]) -> None:
        """Put the background's optics back into the camera's signal buffer inside ``boxes``."""
        if self._bg_signal is not None:
            sig, bg = self._sig[cam], self._bg_signal[cam]
            for u0, v0, u1, v1 in boxes:
                sig[v0:v1, u0:u1] = bg[v0:v1, u0:u1]

    def signal(
        self, shape: ArmShape | Sequence[ArmShape], cam: int = 0, incremental: bool = True
    ) -> NDArray[np.float32]:
        """Noise-free sensor signal [grey levels] (h, w, 3), or (h, w) in grayscale, of camera
        ``cam`` (0 left, 1 right) for an arm shape in {w} (or one shape per marker);
        ``incremental=False`` runs the optics over the whole frame (the reference the
        incremental path must equal). Motion blur, if set, is along the image x axis here."""
        if cam not in (0, 1):
            raise InputError(f"cam must be 0 (left) or 1 (right), got {cam}")
        sig, boxes = self._arm_signal(cam, self._shapes(shape), 0.0, incremental)
        out = sig.copy()
        self._restore(cam, boxes)
        return out

    def _render_camera(self, cam: int, shapes: tuple[ArmShape, ...], count: int, out: NDArray[np.uint8]) -> None:
        """One camera's image (cam 0 = left, 1 = right) of render call number ``count`` into ``out``."""
        rng = np.random.default_rng([self.seed, 1, count, cam])
        angle = float(rng.uniform(0, np.pi)) if self.settings.motion_blur > 0 else 0.0
        key = int(rng.integers(0, 2**63, dtype=np.uint64))
        sig, boxes = self._arm_signal(cam, shapes, angle, incremental=True)
        try:
            sensor_image(sig, self.settings, key, out=out)
        finally:
            self._restore(cam, boxes)

    def _truth(self, shapes: tuple[ArmShape, ...]) -> tuple[ArmTruth, ...]:
        """Each arm's ground truth; with several arms, the corners the others hide are marked."""
        cams = ((self.camera.left, self.T_left_world), (self.camera.right, self.T_right_world))
        prims = [self._primitives(shapes, T_cw) for _, T_cw in cams] if len(shapes) > 1 else None
        out = []
        for i, (shape, marker) in enumerate(zip(shapes, self.markers)):
            corners = []
            for c, (camera, T_cw) in enumerate(cams):
                occ = None
                if prims is not None:
                    others = [p for k, p in enumerate(prims[c]) if k != i]
                    occ = ([cap for cs, _ in others for cap in cs], [s for _, s in others])
                corners.append(corner_truth(camera, marker, T_cw @ shape.T_world_marker, occ))
            tip = shape.tip @ self.T_left_world[:3, :3].T + self.T_left_world[:3, 3]
            out.append(ArmTruth(self.T_left_world @ shape.T_world_marker, tip, corners[0], corners[1]))
        return tuple(out)

    def _render_into(
        self, shapes: tuple[ArmShape, ...], left: NDArray[np.uint8], right: NDArray[np.uint8]
    ) -> tuple[ArmTruth, ...]:
        """Render both cameras into ``left`` and ``right`` (the right one in the renderer's second
        thread: the numba kernels and OpenCV release the GIL); returns the ground truth."""
        count = self._count
        self._count += 1
        job = self._pool.submit(self._render_camera, 1, shapes, count, right)
        try:
            self._render_camera(0, shapes, count, left)
        finally:
            job.result()
        return self._truth(shapes)

    def _image_shape(self, width: int) -> tuple[int, ...]:
        h = self.camera.image_size[1]
        return (h, width, 3) if self.settings.colour else (h, width)

    @staticmethod
    def _pair(left: NDArray[np.uint8], right: NDArray[np.uint8], t: ArmTruth) -> RenderedPair:
        return RenderedPair(left, right, t.T_left_marker, t.tip_left, t.corners_left, t.corners_right)

    def render(self, shape: ArmShape) -> RenderedPair:
        """Render both cameras for an arm shape in {w}; returns images and ground truth (a
        renderer of several markers needs :meth:`render_arms`).

        Not thread-safe (one call at a time: the renderer reuses its buffers)."""
        shapes = self._shapes(shape)
        size = self._image_shape(self.camera.image_size[0])
        left, right = np.empty(size, np.uint8), np.empty(size, np.uint8)
        return self._pair(left, right, self._render_into(shapes, left, right)[0])

    def render_side_by_side(self, shape: ArmShape) -> tuple[NDArray[np.uint8], RenderedPair]:
        """Like :meth:`render`, the two images rendered into one side-by-side image (left | right,
        (h, 2 w, 3) or (h, 2 w)), returned with the pair, whose images are its two halves (views)."""
        shapes = self._shapes(shape)
        w = self.camera.image_size[0]
        both = np.empty(self._image_shape(2 * w), np.uint8)
        return both, self._pair(both[:, :w], both[:, w:], self._render_into(shapes, both[:, :w], both[:, w:])[0])

    def render_arms(self, shapes: Sequence[ArmShape]) -> RenderedScene:
        """Render both cameras for several arms at once, one shape in {w} per marker (same order):
        the arms hide one another where they cross. Returns the images and each arm's truth.
        Not thread-safe (as :meth:`render`, whose noise stream it shares)."""
        arms = self._shapes(shapes)
        size = self._image_shape(self.camera.image_size[0])
        left, right = np.empty(size, np.uint8), np.empty(size, np.uint8)
        return RenderedScene(left, right, self._render_into(arms, left, right))

    def render_arms_side_by_side(self, shapes: Sequence[ArmShape]) -> tuple[NDArray[np.uint8], RenderedScene]:
        """Like :meth:`render_arms`, into one side-by-side image (left | right) returned with the
        scene, whose images are its two halves (views)."""
        arms = self._shapes(shapes)
        w = self.camera.image_size[0]
        both = np.empty(self._image_shape(2 * w), np.uint8)
        return both, RenderedScene(both[:, :w], both[:, w:], self._render_into(arms, both[:, :w], both[:, w:]))
