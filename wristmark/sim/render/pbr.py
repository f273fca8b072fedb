"""Physically based stereo rendering of the marked arm with Mitsuba 3 (``wristmark render
--engine pbr``; the optional extra ``pbr``: ``pip install 'wristmark[pbr]'``, scripts/ensure-pbr.sh).

The same world as :class:`sim.render.stereo_renderer.StereoRenderer` (the arm's capsules and
marker sleeve of :func:`sim.render.stereo_renderer.arm_primitives`, in {w} [m]), path-traced
instead of ray-cast with a shading model: the sleeve is a cylinder whose print (the exact
pattern of :meth:`models.marker.MarkerModel.is_black`, as a bitmap: u = angle / 2 pi from x_wm,
v = (z - z_lo) / height) lies under a clear laminate (Mitsuba ``roughplastic``: GGX roughness
``sleeve_roughness``, index 1.5, F0 = 0.04) or bare (``diffuse``: matte); tube and link are a
dark diffuse, the gripper a rough metal (``roughconductor``, aluminium), the tissue a textured
diffuse plane 120 mm ahead. The light comes from point outputs beside both lenses
(``light_offset`` above and below each lens centre, inverse-square fall-off), so a glossy
sleeve's highlight runs along it where it faces the camera. Each camera is a pinhole or a thin
lens (``aperture_radius``, ``focus_distance``: defocus) rendering a wider undistorted image,
remapped (bilinear) into the calibrated camera's distortion; then the sensor of
:mod:`sim.render.sensor` (shot and read noise, clipping at 255, JPEG) with the render settings.

Exposure: unit Mitsuba radiance is ``EXPOSURE pi D0^2 / n_lights`` grey levels, so a white
patch facing the lights at D0 is as bright as in the fast renderer. Mitsuba is imported on first
use (CPU variant ``llvm_ad_rgb``; it needs LLVM >= 19: ``DRJIT_LIBLLVM_PATH`` is set to
Debian's ``libLLVM.so.19.1`` when present and not set already).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.arm_shape import ArmShape
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.arm import METAL, Capsule
from wristmark.sim.render.raycast import D0
from wristmark.sim.render.sensor import sensor_image
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import EXPOSURE, RenderedPair, arm_primitives, corner_truth

Array = NDArray[np.float64]
LLVM_PATHS = ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "/usr/lib/llvm-19/lib/libLLVM.so.1")
TISSUE_DEPTH = 0.12  # [m] the tissue plane ahead of the left camera
TEXTURE_WIDTH = 2048  # sleeve print: texels around the circumference


@dataclass(frozen=True)
class PbrSettings:
    """Path-tracing settings. spp: samples per pixel; sleeve_specular: the laminate's F0 (0: a
    matte sleeve, bare print; else a clear coat of index (1 + sqrt F0) / (1 - sqrt F0));
    sleeve_roughness: its GGX alpha; light_offset: the light outputs above and below each lens
    [m] (0: at the lens centres); aperture_radius [m] (0: pinhole) and focus_distance [m] of the
    thin lens; max_depth: path length; margin [px]: extra border of the undistorted image."""

    spp: int = 24
    sleeve_specular: float = 0.04
    sleeve_roughness: float = 0.1
    light_offset: float = 0.002
    aperture_radius: float = 0.0
    focus_distance: float = 0.08
    max_depth: int = 4
    margin: int = 8

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        if not 1 <= self.spp <= 4096:
            raise ConfigError(f"'spp' must be in 1..4096, got {self.spp}")
        if not self.sleeve_specular < 0.5:  # (a clear coat's index must stay finite)
            raise ConfigError(f"'sleeve_specular' must be in [0, 0.5), got {self.sleeve_specular}")
        # the sleeve and lights as the fast renderer's settings take them
        replace(RenderSettings(), sleeve_specular=self.sleeve_specular, sleeve_roughness=self.sleeve_roughness,
                light_offset=self.light_offset).validate()
        if not 0 <= self.aperture_radius <= 0.005:
            raise ConfigError(f"'aperture_radius' must be in [0, 0.005] m, got {self.aperture_radius}")
        if not 0.01 <= self.focus_distance <= 1:
            raise ConfigError(f"'focus_distance' must be in [0.01, 1] m, got {self.focus_distance}")
        if not 1 <= self.max_depth <= 16 or not 0 <= self.margin <= 256:
            raise ConfigError(f"'max_depth' must be in 1..16 and 'margin' in 0..256, got {self.max_depth}, "
                              f"{self.margin}")


def load_mitsuba() -> Any:
    """Mitsuba 3 with the CPU variant set (InputError naming the extra when it is missing)."""
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        found = next((p for p in LLVM_PATHS if Path(p).is_file()), None)
        if found is not None:
            os.environ["DRJIT_LIBLLVM_PATH"] = found
    try:
        import mitsuba as mi  # type: ignore[import-not-found,import-untyped,unused-ignore]
    except ImportError as e:
        raise InputError("--engine pbr needs Mitsuba 3: pip install 'wristmark[pbr]' (scripts/ensure-pbr.sh)") from e
    try:
        mi.set_variant("llvm_ad_rgb")
    except (AttributeError, ImportError, RuntimeError) as e:
        raise InputError(f"Mitsuba's CPU variant llvm_ad_rgb failed ({e}): it needs LLVM >= 19 "
                         "(Debian libllvm19; DRJIT_LIBLLVM_PATH)") from e
    return mi


def sleeve_texture(marker: MarkerModel, width: int = TEXTURE_WIDTH) -> NDArray[np.float32]:
    """The sleeve's print as an RGB reflectance bitmap (rows: z from z_lo (row 0) to z_hi,
    columns: angle from 0 to 2 pi), texel centres sampled with the marker's own pattern."""
    z_lo, z_hi = marker.z_extent
    height = max(8, int(round(width * (z_hi - z_lo) / (2 * np.pi * marker.radius))))
    ang = (np.arange(width) + 0.5) / width * 2 * np.pi
    zs = z_lo + (np.arange(height) + 0.5) / height * (z_hi - z_lo)
    black = np.array([[marker.is_black(float(a), float(z)) for a in ang] for z in zs])
    tex = np.where(black[..., None], np.float32(0.05), np.float32(0.86)) * np.ones(3, np.float32)
    return np.ascontiguousarray(tex, np.float32)


def _tissue_texture(rng: np.random.Generator, n: int = 256) -> NDArray[np.float32]:
    """Smooth reddish tissue reflectance (RGB) with faint vessels."""
    base = cv2.GaussianBlur(rng.normal(size=(n, n)).astype(np.float32), (0, 0), 6.0)
    base = 0.5 + 0.5 * base / (np.abs(base).max() + 1e-9)
    img = np.stack([0.55 + 0.12 * base, 0.22 + 0.06 * base, 0.18 + 0.05 * base], axis=2)
    for _ in range(6):  # vessels: dark curves
        pts = np.cumsum(rng.normal(scale=12.0, size=(12, 2)), axis=0) + rng.uniform(0, n, 2)
        cv2.polylines(img, [pts.astype(np.int32)], False, (0.3, 0.08, 0.1), 1, cv2.LINE_AA)
    return np.ascontiguousarray(img, np.float32)


class PinholeRemap:
    """The wider undistorted pinhole image a Mitsuba camera renders for one calibrated camera, and
    the remap of it into the camera's raw (distorted) pixels."""

    def __init__(self, camera: Camera, size: tuple[int, int], margin: int) -> None:
        w, h = size
        u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
        xy = camera.undistort(np.column_stack([u.ravel(), v.ravel()])).reshape(h, w, 2)
        self.f = float(camera.K[0, 0])
        half = np.abs(xy).reshape(-1, 2).max(axis=0) * self.f + margin
        self.width, self.height = int(2 * np.ceil(half[0])), int(2 * np.ceil(half[1]))
        self.fov_x = float(np.degrees(2 * np.arctan(0.5 * self.width / self.f)))
        # pinhole pixel (column, row) of each raw pixel's ray (square pixels of focal f): x f + W / 2 - 1/2
        self.map_x = np.asarray(xy[..., 0] * self.f + 0.5 * self.width - 0.5, np.float32)
        self.map_y = np.asarray(xy[..., 1] * self.f + 0.5 * self.height - 0.5, np.float32)

    def remap(self, img: NDArray[np.float32]) -> NDArray[np.float32]:
        """The raw camera's image from the pinhole one (bilinear)."""
        return np.asarray(cv2.remap(img, self.map_x, self.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
                          np.float32)


class PbrStereoRenderer:
    """Path-traced stereo pairs of the arm (module doc) with the same ground truth as
    :class:`sim.render.stereo_renderer.StereoRenderer`; deterministic per ``seed``."""

    def __init__(self, camera: StereoCamera, marker: MarkerModel, settings: RenderSettings, pbr: PbrSettings,
                 seed: int = 0) -> None:
        camera.validate()
        marker.validate()
        settings.validate()
        pbr.validate()
        if camera.T_world_left is None:
            raise InputError("the calibration has no 'world_T_left': add it to render the arm in {w}")
        self.mi = load_mitsuba()
        self.camera, self.marker, self.settings, self.pbr, self.seed = camera, marker, settings, pbr, int(seed)
        self._count = 0
        W = np.asarray(camera.T_world_left, float)
        self.T_left_world = np.linalg.inv(W)
        T_rl = np.eye(4)
        T_rl[:3, :3], T_rl[:3, 3] = np.asarray(camera.R, float), np.asarray(camera.T, float).reshape(3)
        self.T_right_world = T_rl @ self.T_left_world
        self._remaps = tuple(PinholeRemap(c, camera.image_size, pbr.margin) for c in (camera.left, camera.right))
        self._texture = sleeve_texture(marker)  # (a fresh Mitsuba tensor per scene: loading consumes it)
        self._tissue = _tissue_texture(np.random.default_rng([self.seed, 3]))

    def _lights(self) -> list[Array]:
        """Light outputs in {w} [m]: above and below (or at) each lens centre, along the left camera's y."""
        W = np.linalg.inv(self.T_left_world)
        centres = [W[:3, 3], np.linalg.inv(self.T_right_world)[:3, 3]]
        y = W[:3, 1]
        o = self.pbr.light_offset
        offs = [0.0] if o == 0 else [o, -o]
        return [c + k * y for c in centres for k in offs]

    def _scene(self, shape: ArmShape) -> dict[str, Any]:
        mi, st = self.mi, self.pbr
        T = mi.ScalarTransform4f
        caps, sleeve = arm_primitives(shape, self.marker, np.eye(4))
        scene: dict[str, Any] = {"type": "scene", "integrator": {"type": "path", "max_depth": st.max_depth}}
        dark = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.18, 0.2, 0.22]}}
        metal = {"type": "roughconductor", "material": "Al", "distribution": "ggx", "alpha": 0.15}
        for i, c in enumerate(caps):
            bsdf = metal if c.material is METAL else dark
            self._capsule(scene, f"cap{i}", c, bsdf)
        z_lo, z_hi = self.marker.z_extent
        r = self.marker.radius
        to_world = T(np.asarray(sleeve.T_cam_marker, float)) @ T().translate([0.0, 0.0, z_lo]) @ T().scale(
            [r, r, z_hi - z_lo])
        tex = {"type": "bitmap", "data": mi.TensorXf(self._texture), "raw": True, "filter_type": "bilinear"}
        if st.sleeve_specular > 0:
            s = float(np.sqrt(st.sleeve_specular))
            print_bsdf = {"type": "roughplastic", "distribution": "ggx", "alpha": st.sleeve_roughness,
                          "int_ior": (1 + s) / (1 - s), "ext_ior": 1.0, "diffuse_reflectance": tex}
        else:
            print_bsdf = {"type": "diffuse", "reflectance": tex}
        scene["sleeve"] = {"type": "cylinder", "to_world": to_world, "bsdf": print_bsdf}
        for k, z in (("lo", z_lo), ("hi", z_hi)):  # the black end rings
            scene[f"ring_{k}"] = {"type": "disk", "to_world": T(np.asarray(sleeve.T_cam_marker, float))
                                  @ T().translate([0.0, 0.0, z]) @ T().scale([r, r, 1.0])
                                  @ T().rotate([1.0, 0.0, 0.0], 0.0 if k == "hi" else 180.0),
                                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.05}}}
        W = np.linalg.inv(self.T_left_world)
        centre = W[:3, 3] + TISSUE_DEPTH * W[:3, 2]
        R = W[:3, :3]
        M = np.eye(4)
        M[:3, :3], M[:3, 3] = R * 0.09, centre  # a 180 mm square facing the camera
        tissue = {"type": "bitmap", "data": mi.TensorXf(self._tissue), "raw": True}
        scene["tissue"] = {"type": "rectangle", "to_world": T(M) @ T().rotate([1.0, 0.0, 0.0], 180.0),
                           "bsdf": {"type": "diffuse", "reflectance": tissue}}
        for i, p in enumerate(self._lights()):
            scene[f"light{i}"] = {"type": "point", "position": [float(x) for x in p],
                                  "intensity": {"type": "rgb", "value": 1.0}}
        return scene

    def _capsule(self, scene: dict[str, Any], name: str, c: Capsule, bsdf: dict[str, Any]) -> None:
        a, b = np.asarray(c.a, float), np.asarray(c.b, float)
        if np.linalg.norm(b - a) > 1e-9:
            scene[name] = {"type": "cylinder", "p0": [float(x) for x in a], "p1": [float(x) for x in b],
                           "radius": float(c.r), "bsdf": bsdf}
        for k, (p, on) in enumerate(zip((a, b), c.caps)):
            if on:
                scene[f"{name}_end{k}"] = {"type": "sphere", "center": [float(x) for x in p], "radius": float(c.r),
                                           "bsdf": bsdf}

    def _sensor(self, cam: int) -> dict[str, Any]:
        mi, st = self.mi, self.pbr
        rm = self._remaps[cam]
        T_wc = np.linalg.inv((self.T_left_world, self.T_right_world)[cam])
        flip = np.diag([-1.0, -1.0, 1.0, 1.0])  # OpenCV's camera axes (x right, y down) -> Mitsuba's (x left, y up)
        sensor: dict[str, Any] = {
            "type": "thinlens" if st.aperture_radius > 0 else "perspective",
            "fov": rm.fov_x, "fov_axis": "x", "near_clip": 0.002, "far_clip": 1.0,
            "to_world": mi.ScalarTransform4f(T_wc @ flip),
            "film": {"type": "hdrfilm", "width": rm.width, "height": rm.height, "pixel_format": "rgb",
                     "rfilter": {"type": "gaussian", "stddev": 0.5}},
            "sampler": {"type": "independent", "sample_count": st.spp},
        }
        if st.aperture_radius > 0:
            sensor["aperture_radius"] = st.aperture_radius
            sensor["focus_distance"] = st.focus_distance
        return sensor

    def radiance(self, shape: ArmShape, cam: int, seed: int = 0) -> NDArray[np.float32]:
        """Camera ``cam``'s (0 left, 1 right) path-traced radiance [grey levels], BGR (h, w, 3),
        in its raw (distorted) pixels."""
        mi = self.mi
        scene = self._scene(shape)
        scene["sensor"] = self._sensor(cam)
        img = np.asarray(mi.render(mi.load_dict(scene), seed=int(seed)), np.float32)
        gain = EXPOSURE * np.pi * D0 ** 2 / len(self._lights())
        raw = self._remaps[cam].remap(np.ascontiguousarray(img[..., ::-1] * np.float32(gain)))
        return raw

    def render(self, shape: ArmShape) -> RenderedPair:
        """Both cameras path-traced, through the sensor, with the ground truth."""
        count = self._count
        self._count += 1
        out: list[NDArray[np.uint8]] = []
        for cam in (0, 1):
            rng = np.random.default_rng([self.seed, 1, count, cam])
            sig = self.radiance(shape, cam, seed=int(rng.integers(0, 2**31 - 1)))
            if not self.settings.colour:
                sig = np.asarray(cv2.cvtColor(sig, cv2.COLOR_BGR2GRAY), np.float32)
            out.append(sensor_image(sig, self.settings, int(rng.integers(0, 2**63, dtype=np.uint64))))
        T_lm = self.T_left_world @ shape.T_world_marker
        T_rm = self.T_right_world @ shape.T_world_marker
        tip = shape.tip @ self.T_left_world[:3, :3].T + self.T_left_world[:3, 3]
        return RenderedPair(out[0], out[1], T_lm, tip, corner_truth(self.camera.left, self.marker, T_lm),
                            corner_truth(self.camera.right, self.marker, T_rm))
