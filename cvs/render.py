"""Stereo image synthesis of the marked arm: :class:`StereoRenderer` -> :class:`StereoFrame`.

Each camera sees the same world: the distal arm (tube along the true centreline, rigid link,
checkered marker sleeve, gripper) ray-cast through the camera's exact distortion at
``settings.supersampling`` samples per pixel axis over a cached tissue background, then the
optics and sensor of :mod:`cvs.render_optics`. Ground truth (pose of {wm} in {ll}, tip in {ll},
raw pixel corners with their cos_view per camera) follows DESIGN.md's truth.json.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from cvs.camera import Camera, StereoCamera
from cvs.marker import MarkerModel
from cvs.render_arm import METAL, TUBE, ArmLayer, Capsule, RayMap, Sleeve, render_arm, sleeve_box
from cvs.render_background import stereo_backgrounds
from cvs.render_optics import apply_optics, vignetting_map
from cvs.render_settings import RenderSettings
from models.arm_shape import ArmShape
from models.errors import InputError

Array = NDArray[np.float64]
EXPOSURE = 200.0  # grey levels for unit radiance (white patch facing the light at D0)
GRIPPER_RADIUS = 0.0016  # [m]
JAW_RADIUS = 0.0006  # [m]


@dataclass(frozen=True)
class CornerTruth:
    """One marker corner in one camera: raw pixel uv [px] and cos_view (<= 0: facing away)."""

    index: int
    uv: tuple[float, float]
    cos_view: float


@dataclass(frozen=True)
class StereoFrame:
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


def corner_truth(camera: Camera, marker: MarkerModel, T_cam_marker: Array) -> tuple[CornerTruth, ...]:
    """Raw pixels and cos_view of every marker corner for a camera seeing {wm} at T_cam_marker."""
    R, t = T_cam_marker[:3, :3], T_cam_marker[:3, 3]
    P = marker.corners() @ R.T + t
    N = marker.corner_normals() @ R.T
    uv = camera.project(P)
    cos = -(N * P).sum(axis=1) / np.linalg.norm(P, axis=1)
    return tuple(CornerTruth(i, (float(uv[i, 0]), float(uv[i, 1])), float(cos[i])) for i in range(marker.columns))


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
    h = marker.row_height
    end = cam(shape.frames.T_world_2e[:3, 3])
    caps.append(Capsule(end, o - 0.5 * h * z, shape.radius, METAL))  # rigid link into the sleeve
    tip = cam(shape.tip)
    base = tip - 0.0045 * z
    caps.append(Capsule(o + h * z, base, GRIPPER_RADIUS, METAL))
    for sgn in (1.0, -1.0):  # two jaws, slightly open
        caps.append(Capsule(base + sgn * 0.0008 * x, tip + sgn * 0.0012 * x, JAW_RADIUS, METAL))
    return caps, Sleeve(T_cm, marker)


class StereoRenderer:
    """Renders the arm in a calibrated stereo endoscope (needs ``camera.T_world_left``).

    Deterministic per ``seed``: the background is drawn once; the k-th call of :meth:`render`
    uses noise stream (seed, k).
    """

    def __init__(self, camera: StereoCamera, marker: MarkerModel, settings: RenderSettings, seed: int = 0) -> None:
        camera.validate()
        marker.validate()
        settings.validate()
        if camera.T_world_left is None:
            raise InputError("the calibration has no 'world_T_left': add it to render the arm in {w}")
        cv2.setNumThreads(1)
        self.camera, self.marker, self.settings, self.seed = camera, marker, settings, int(seed)
        self._count = 0
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="render-right")
        self._maps = (RayMap(camera.left, camera.image_size), RayMap(camera.right, camera.image_size))
        disparity = float(camera.left.K[0, 0]) * camera.baseline / 0.12  # tissue ~120 mm away
        bg_rng = np.random.default_rng([self.seed, 0])
        self._bg = stereo_backgrounds(bg_rng, camera.image_size, disparity, EXPOSURE * 0.9)
        vig = vignetting_map(camera.image_size, settings.vignetting)
        self._vignette: NDArray[np.float32] = np.asarray(cv2.merge([vig] * 3) if settings.colour else vig, np.float32)
        W = np.asarray(camera.T_world_left, float)
        self.T_left_world = np.linalg.inv(W)
        T_right_left = np.eye(4)
        T_right_left[:3, :3], T_right_left[:3, 3] = camera.R, camera.T
        self.T_right_world = T_right_left @ self.T_left_world

    @staticmethod
    def _compose(img: NDArray[np.float32], bg: NDArray[np.float32], layer: ArmLayer | None) -> None:
        if layer is None:
            return
        h, w = bg.shape[:2]
        u0, v0 = layer.box[:2]
        u1, v1 = min(layer.box[2], w), min(layer.box[3], h)  # tiles may overhang the image
        ss = layer.ss
        crop = bg[v0:v1, u0:u1]
        up = np.repeat(np.repeat(crop, ss, axis=0), ss, axis=1)
        hs, ws = (v1 - v0) * ss, (u1 - u0) * ss
        mix = np.where(layer.hit[:hs, :ws, None], layer.radiance[:hs, :ws], up)
        img[v0:v1, u0:u1] = cv2.resize(mix, (u1 - u0, v1 - v0), interpolation=cv2.INTER_AREA)

    def _render_camera(self, cam: int, shape: ArmShape, count: int) -> NDArray[np.uint8]:
        """One camera's image (cam 0 = left, 1 = right) of render call number ``count``."""
        T_cw = (self.T_left_world, self.T_right_world)[cam]
        rmap, bg = self._maps[cam], self._bg[cam]
        rng = np.random.default_rng([self.seed, 1, count, cam])
        ss = self.settings.supersampling
        caps, sleeve = arm_primitives(shape, self.marker, T_cw)
        img = bg.copy()
        mbox = sleeve_box(rmap, sleeve) if ss != self.settings.arm_supersampling else None
        arm_ss = self.settings.arm_supersampling
        self._compose(img, bg, render_arm(rmap, caps, sleeve, arm_ss, EXPOSURE, exclude=mbox))
        if mbox is not None:  # the marker and what surrounds it at full supersampling
            self._compose(img, bg, render_arm(rmap, caps, sleeve, ss, EXPOSURE, clip=mbox))
        return apply_optics(img, self.settings, self._vignette, rng)

    def render(self, shape: ArmShape) -> StereoFrame:
        """Render both cameras for an arm shape in {w}; returns images and ground truth.

        The two cameras render in two threads (numpy and OpenCV release the GIL)."""
        count = self._count
        self._count += 1
        right = self._pool.submit(self._render_camera, 1, shape, count)
        images = [self._render_camera(0, shape, count), right.result()]
        T_lm = self.T_left_world @ shape.T_world_marker
        T_rm = self.T_right_world @ shape.T_world_marker
        tip = shape.tip @ self.T_left_world[:3, :3].T + self.T_left_world[:3, 3]
        return StereoFrame(
            images[0],
            images[1],
            T_lm,
            tip,
            corner_truth(self.camera.left, self.marker, T_lm),
            corner_truth(self.camera.right, self.marker, T_rm),
        )
