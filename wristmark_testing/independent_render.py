"""Independent stereo renderer of the wrist marker, written from docs/design.md alone.

It writes datasets in docs/design.md's "Stereo dataset format" that the project's own renderer never made:
its own stereo camera (drawn per dataset), its own scene (a plain tube carrying the marker sleeve, a
textured tissue-like plane behind it, a light at the endoscope tip between the eyes), its own optics and
sensor model. Only numpy, opencv, yaml and json are used: never the project's packages.

Conventions (docs/design.md): SI units (metres, radians); OpenCV camera frames (x right, y down, z forward);
{ll} is the left camera frame, ``X_right = R X_left + T``; pixel (0, 0) is the centre of the top-left
pixel; the marker frame {wm} has z along the arm's distal direction and x through corner 0; corner i is
``[r cos(i beta), r sin(i beta), 0]``; upper-row (0 < z < row_height) patch k is black for even k. A coded
marker's ``patches`` [a0, a1, z0, z1] (angle from x_wm towards y_wm [rad], wrapping beyond 2 pi; z [m]) are
dark too ("The coded marker"); the sleeve is white elsewhere and spans [min z, max z] of rows and patches.

Rendering: per-pixel ray casting. Rays come from raw (distorted) pixel positions through
``cv2.undistortPoints`` (iterated to convergence); in the region of the arm every pixel is traced at its
four corners (2x2 box) and pixels whose corner samples disagree in material (edges, silhouettes) or that see
the sleeve at a grazing angle are supersampled 4x4 (box filter). The background plane uses exact rays on a
4-pixel grid, interpolated. Shading is Lambert + a Blinn-Phong lobe under a point
light at the endoscope tip with inverse-square falloff; then Gaussian optics blur, vignetting, gamma,
shot + read noise, 8-bit quantisation and an optional JPEG round trip.

Command line: ``python -m wristmark_testing.independent_render --out DIR [--pairs N] [--seed S] [--scale F]
[--columns C] [--radius M] [--jpeg Q] [--gray] [--direction right|left|random] [--glare] [--no-body]
[--marker-file YAML]``.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-12)  # round trip < 1e-10 px

# material labels of the ray tracer
BG, TUBE, CAP, ANNULUS, SLEEVE0 = 0, 1, 2, 3, 10


@dataclass
class Eye:
    """One camera: K [px], OpenCV distortion (k1, k2, p1, p2, k3), pose ``X_eye = R X_left + T`` [m]."""

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    T: np.ndarray

    @property
    def centre(self) -> np.ndarray:
        """Optical centre in {ll} [m]."""
        return -self.R.T @ self.T


@dataclass
class Rig:
    """Stereo camera: image size (width, height) [px] and both eyes (left is the reference {ll})."""

    size: tuple[int, int]
    left: Eye
    right: Eye

    @property
    def light(self) -> np.ndarray:
        """Position of the light (endoscope tip, midway between the eyes) in {ll} [m]."""
        return 0.5 * (self.left.centre + self.right.centre)


@dataclass
class Marker:
    """Marker sleeve [m]: radius, patch columns, row height, tip offset along z_wm."""

    radius: float = 0.00455
    columns: int = 12
    row_height: float = 0.0025
    tip_offset: float = 0.015
    patches: tuple[tuple[float, float, float, float], ...] = ()

    @property
    def z_range(self) -> tuple[float, float]:
        """The sleeve's extent along z [m]: the rows and every patch."""
        return (min([-self.row_height] + [p[2] for p in self.patches]),
                max([self.row_height] + [p[3] for p in self.patches]))

    def dark(self, ang: np.ndarray, z: np.ndarray) -> np.ndarray:
        """True where the sleeve is dark at angles ang [rad] and heights z [m] (docs/design.md)."""
        a = np.mod(ang, 2 * math.pi)
        k = np.minimum((a / self.beta).astype(np.int64), self.columns - 1)
        out = (np.abs(z) < self.row_height) & ((k % 2 == 0) == (z > 0))
        for a0, a1, z0, z1 in self.patches:
            out |= (z >= z0) & (z < z1) & (np.mod(a - a0, 2 * math.pi) < a1 - a0)
        return out

    @property
    def beta(self) -> float:
        """Angular width of one column [rad]."""
        return 2 * math.pi / self.columns

    def corners(self) -> np.ndarray:
        """X-corners in {wm}, shape (columns, 3) [m]."""
        a = self.beta * np.arange(self.columns)
        return np.stack([self.radius * np.cos(a), self.radius * np.sin(a), np.zeros_like(a)], axis=1)


@dataclass
class Look:
    """Appearance and sensor settings (albedos linear in [0, 1]; colours are B, G, R)."""

    tube_radius: float = 0.0037  # m, the arm (outer diameter 7.4 mm)
    tube_proximal: float = 0.035  # m of tube behind the sleeve (proximal)
    white: tuple[float, float, float] = (0.72, 0.74, 0.75)
    black: tuple[float, float, float] = (0.035, 0.035, 0.04)
    annulus: tuple[float, float, float] = (0.45, 0.45, 0.45)
    tube: tuple[float, float, float] = (0.24, 0.2, 0.17)  # bluish-grey plastic (BGR)
    cap: tuple[float, float, float] = (0.3, 0.3, 0.32)
    spec_sleeve: float = 0.15
    shin_sleeve: float = 50.0
    spec_tube: float = 0.35
    shin_tube: float = 20.0
    d_ref: float = 0.08  # m: distance at which the light's irradiance is 1
    gamma: float = 2.2
    blur_sigma: float = 0.8  # px, optics
    read_noise: float = 1.5  # grey levels (std)
    shot_gain: float = 0.06  # shot-noise variance per grey level of signal
    vignette: float = 0.25  # relative fall-off at the image corner
    auto_exposure: bool = True  # scale exposure by (marker distance / d_ref)^2 (else saturation up close)
    supersample: int = 4
    jpeg: int | None = None
    gray: bool = False
    direction: str = "right"  # tip direction in the image: right, left or random
    body: bool = True  # the arm's tube continues behind (proximal to) the sleeve


# ----------------------------------------------------------------------------------------------------------
# camera and poses


def rot(rvec: np.ndarray | list[float]) -> np.ndarray:
    """Rotation matrix of a rotation vector [rad]."""
    return cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))[0]


def random_rig(rng: np.random.Generator, scale: float = 1.0) -> Rig:
    """A stereo endoscope unlike the project's default: fx 1200-1500 px, off-centre principal points,
    4-6 mm baseline, k1 in [-0.3, -0.15] with k2, p1, p2, a small rotation between the eyes; 1920x1080 at
    ``scale`` 1 (K scaled about the pixel-centre convention for other scales)."""
    w, h = round(1920 * scale), round(1080 * scale)
    eyes = []
    fx0 = rng.uniform(1200, 1500)
    for _ in range(2):
        fx = fx0 * rng.uniform(0.99, 1.01)
        fy = fx * rng.uniform(0.995, 1.005)
        cx = 959.5 + rng.uniform(-40, 40)
        cy = 539.5 + rng.uniform(-30, 30)
        K = np.array([[fx * scale, 0, (cx + 0.5) * scale - 0.5], [0, fy * scale, (cy + 0.5) * scale - 0.5], [0, 0, 1]])
        dist = np.array([rng.uniform(-0.3, -0.15), rng.uniform(0.03, 0.12), rng.uniform(-1e-3, 1e-3),
                         rng.uniform(-1e-3, 1e-3), 0.0])
        eyes.append([K, dist])
    baseline = rng.uniform(0.004, 0.006)
    R = rot(rng.uniform(-1, 1, 3) * np.radians([0.6, 1.2, 0.4]))
    # right eye centre at +baseline along x of {ll} (plus small offsets): T = -R C
    C = np.array([baseline, rng.uniform(-1e-4, 1e-4), rng.uniform(-1e-4, 1e-4)])
    T = -R @ C
    return Rig((w, h), Eye(eyes[0][0], eyes[0][1], np.eye(3), np.zeros(3)), Eye(eyes[1][0], eyes[1][1], R, T))


def rays(eye: Eye, uv: np.ndarray) -> np.ndarray:
    """Unit ray directions in {ll} through raw pixel positions ``uv`` (N, 2) [px]."""
    n = cv2.undistortPoints(uv.reshape(-1, 1, 2).astype(np.float64), eye.K, eye.dist, criteria=UNDISTORT_CRITERIA)
    d = np.concatenate([n.reshape(-1, 2), np.ones((len(uv), 1))], axis=1) @ eye.R  # R^T d, row-wise
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def project(eye: Eye, X: np.ndarray) -> np.ndarray:
    """Raw pixels (N, 2) of points X (N, 3) in {ll} [m]."""
    uv, _ = cv2.projectPoints(X.reshape(-1, 1, 3).astype(np.float64), cv2.Rodrigues(eye.R)[0],
                              eye.T.astype(np.float64), eye.K, eye.dist)
    return uv.reshape(-1, 2)


def cos_view(eye: Eye, X: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Cosine between normals n (N, 3) at X (N, 3) and the direction to the eye's centre (all in {ll})."""
    d = eye.centre[None, :] - X
    return np.sum(d * n, axis=1) / np.linalg.norm(d, axis=1)


def random_pose(rng: np.random.Generator, rig: Rig, marker: Marker, look: Look, tries: int = 500,
                ) -> tuple[np.ndarray, np.ndarray]:
    """Pose (R, t) of {wm} in {ll} [m]: 60-100 mm deep, axis roughly horizontal in the image (in-image
    angle within +-20 deg, out of the image plane within +-35 deg), random roll; redrawn until 4-7 corners
    face each eye, at least 3 are well visible (cos_view > 0.3) and everything visible lies in the images."""
    w, h = rig.size
    a = marker.beta * np.arange(marker.columns)
    N = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    for _ in range(tries):
        sign = {"right": 1.0, "left": -1.0}.get(look.direction, float(rng.choice([-1.0, 1.0])))
        az = math.radians(rng.uniform(-20, 20))
        el = math.radians(rng.uniform(-35, 35))
        z = sign * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        ref = np.array([0.0, 0.0, -1.0]) - z * (-z[2])
        x0 = ref / np.linalg.norm(ref)
        y0 = np.cross(z, x0)
        roll = rng.uniform(0, 2 * math.pi)
        x = math.cos(roll) * x0 + math.sin(roll) * y0
        Rm = np.stack([x, np.cross(z, x), z], axis=1)
        depth = rng.uniform(0.06, 0.10)
        uv0 = np.array([rng.uniform(0.3, 0.7) * w, rng.uniform(0.3, 0.7) * h])
        n = cv2.undistortPoints(uv0.reshape(1, 1, 2), rig.left.K, rig.left.dist, criteria=UNDISTORT_CRITERIA)
        t = depth * np.array([n[0, 0, 0], n[0, 0, 1], 1.0])
        X = t + marker.corners() @ Rm.T
        tip = t + Rm[:, 2] * marker.tip_offset
        ok = True
        for eye in (rig.left, rig.right):
            c = cos_view(eye, X, N @ Rm.T)
            uv = project(eye, np.vstack([X[c > 0], tip]))
            m = 0.04 * w
            if not (4 <= np.sum(c > 0) <= 7 and np.sum(c > 0.3) >= 3):
                ok = False
            if not (np.all(uv[:, 0] > m) and np.all(uv[:, 0] < w - 1 - m) and np.all(uv[:, 1] > m)
                    and np.all(uv[:, 1] < h - 1 - m)):
                ok = False
        if ok:
            return Rm, t
    raise RuntimeError("no admissible marker pose found")


# ----------------------------------------------------------------------------------------------------------
# scene


def make_texture(rng: np.random.Generator, size: int = 2048) -> np.ndarray:
    """Tissue-like BGR albedo texture (size x size, float32 in [0, 1]): multi-scale smoothed noise,
    dark vessels (anti-aliased polylines) and a few straight fibres."""
    tex = np.zeros((size, size), np.float32)
    for cells, amp in ((8, 0.45), (32, 0.3), (128, 0.18), (512, 0.08)):
        f = rng.standard_normal((cells, cells)).astype(np.float32)
        f = cv2.GaussianBlur(f, (0, 0), 1.0)
        f /= f.std() + 1e-6
        tex += amp * cv2.resize(f, (size, size), interpolation=cv2.INTER_CUBIC)
    base = np.array([0.2, 0.24, 0.58], np.float32)  # B, G, R
    img = base[None, None, :] * np.clip(1.0 + 0.35 * tex, 0.3, 1.8)[:, :, None]
    img[:, :, 1] *= np.clip(1.0 + 0.1 * tex, 0.5, 1.5)
    vessels = np.zeros((size, size), np.uint8)
    for _ in range(int(rng.integers(10, 20))):
        p = rng.uniform(0, size, 2)
        ang = rng.uniform(0, 2 * math.pi)
        pts = []
        for _ in range(int(rng.integers(8, 25))):
            pts.append(p.copy())
            ang += rng.normal(0, 0.35)
            p = p + rng.uniform(20, 60) * np.array([math.cos(ang), math.sin(ang)])
        width = int(rng.integers(1, 5))
        cv2.polylines(vessels, [np.round(np.array(pts) * 16).astype(np.int32)], False, 255, width, cv2.LINE_AA, 4)
    v = cv2.GaussianBlur(vessels.astype(np.float32) / 255.0, (0, 0), 1.2)[:, :, None]
    img = img * (1 - 0.55 * v) + v * 0.55 * np.array([0.08, 0.05, 0.3], np.float32)
    fibres = np.zeros((size, size), np.uint8)
    for _ in range(int(rng.integers(3, 7))):
        p, q = rng.uniform(0, size, 2), rng.uniform(0, size, 2)
        cv2.line(fibres, tuple(int(c) for c in p), tuple(int(c) for c in q), 255, int(rng.integers(1, 3)), cv2.LINE_AA)
    f = cv2.GaussianBlur(fibres.astype(np.float32) / 255.0, (0, 0), 0.8)[:, :, None]
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    img = np.clip(img * (1 + sign * 0.8 * f), 0, 1)
    return img.astype(np.float32)


@dataclass
class Background:
    """A textured plane in {ll}: point ``p0`` [m], unit normal ``n`` (towards the camera), in-plane axes
    ``e1, e2``, texture with ``texel`` metres per texel and offset ``off`` [texels]."""

    p0: np.ndarray
    n: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    texel: float
    off: np.ndarray


def random_background(rng: np.random.Generator, t: np.ndarray, tex_size: int) -> Background:
    """A tissue plane 20-45 mm behind the marker, tilted up to 25 deg."""
    depth = t[2] + rng.uniform(0.02, 0.045)
    n = np.array([0.0, 0.0, -1.0])
    n = rot(rng.uniform(-1, 1, 3) * np.radians([25, 25, 0])) @ n
    e1 = np.cross(n, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    ang = rng.uniform(0, 2 * math.pi)
    e1, e2 = math.cos(ang) * e1 + math.sin(ang) * e2, -math.sin(ang) * e1 + math.cos(ang) * e2
    texel = 0.2e-3 / 2.0
    return Background(np.array([0, 0, depth]), n, e1, e2, texel, rng.uniform(0.3, 0.7, 2) * tex_size)


def shade(n: np.ndarray, X: np.ndarray, eye_c: np.ndarray, light: np.ndarray, albedo: np.ndarray,
          ks: np.ndarray, shin: np.ndarray, d_ref: float) -> np.ndarray:
    """Radiance (N, 3) of surface points X with normals n (in {ll}) under the point light: Lambert plus
    a Blinn-Phong lobe, irradiance (d_ref / distance)^2."""
    lv = light[None, :] - X
    dl = np.linalg.norm(lv, axis=1, keepdims=True)
    lv = lv / dl
    vv = eye_c[None, :] - X
    vv /= np.linalg.norm(vv, axis=1, keepdims=True)
    hv = lv + vv
    hv /= np.linalg.norm(hv, axis=1, keepdims=True)
    ndl = np.clip(np.sum(n * lv, axis=1, keepdims=True), 0, None)
    ndh = np.clip(np.sum(n * hv, axis=1, keepdims=True), 0, None)
    E = (d_ref / dl) ** 2
    return E * (albedo * ndl + ks[:, None] * ndh ** shin[:, None] * (ndl > 0))


def background_radiance(rig: Rig, eye: Eye, dirs: np.ndarray, bg: Background, tex: np.ndarray, d_ref: float,
                        ) -> np.ndarray:
    """Radiance image (H, W, 3) of the background plane seen along per-pixel rays ``dirs`` (H*W, 3)."""
    w, h = rig.size
    c = eye.centre
    s = ((bg.p0 - c) @ bg.n) / (dirs @ bg.n)  # ray length to the plane [m]
    q = (c - bg.p0)[None, :] + s[:, None] * dirs  # hit point relative to p0 [m]
    mx = ((q @ bg.e1) / bg.texel + bg.off[0]).astype(np.float32).reshape(h, w)
    my = ((q @ bg.e2) / bg.texel + bg.off[1]).astype(np.float32).reshape(h, w)
    alb = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)
    lv = (rig.light - bg.p0)[None, :] - q  # to the light
    dl2 = np.einsum("ij,ij->i", lv, lv)
    ndl = np.abs(lv @ bg.n) / np.sqrt(dl2)
    E = (d_ref**2 / dl2 * ndl).astype(np.float32).reshape(h, w, 1)
    return alb * E


def trace(dirs: np.ndarray, origin: np.ndarray, Rm: np.ndarray, t: np.ndarray, marker: Marker, look: Look,
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cast rays (origin in {ll}, unit dirs (N, 3) in {ll}) at the sleeve, tube and caps.

    Returns per ray: material label (BG, TUBE, CAP, ANNULUS or SLEEVE0 + 2 (row * columns + k) + dark, row 0
    upper, 1 lower, 2 outside the checker rows, dark 1 where the sleeve is dark there), hit point and normal
    in {ll} [m], and the cosine between the normal and the reversed ray (for grazing detection)."""
    o = Rm.T @ (origin - t)  # ray origin in {wm}
    d = dirs @ Rm  # R^T d, row-wise
    n_rays = len(d)
    best = np.full(n_rays, np.inf)
    label = np.zeros(n_rays, np.int32)
    nrm = np.zeros((n_rays, 3))
    (s_lo, s_hi), rs, rt = marker.z_range, marker.radius, look.tube_radius
    z_lo, z_hi = s_lo - (look.tube_proximal if look.body else 0.0), marker.tip_offset

    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (o[0] * d[:, 0] + o[1] * d[:, 1])
    for radius, zmin, zmax, lab in ((rs, s_lo, s_hi, SLEEVE0), (rt, z_lo, z_hi, TUBE)):
        c = o[0] ** 2 + o[1] ** 2 - radius**2
        disc = b * b - 4 * a * c
        with np.errstate(invalid="ignore", divide="ignore"):
            s = (-b - np.sqrt(disc)) / (2 * a)
        z = o[2] + s * d[:, 2]
        hit = (disc > 0) & (a > 1e-12) & (s > 0) & (z > zmin) & (z < zmax) & (s < best)
        best[hit] = s[hit]
        label[hit] = lab
        p = o[None, :] + s[hit, None] * d[hit]
        nrm[hit] = np.stack([p[:, 0], p[:, 1], np.zeros(len(p))], axis=1) / radius
    # planar faces: sleeve ends (annuli at z = +-h) and the tube's end caps
    for zp, rin, rout, nz, lab in ((s_hi, rt, rs, 1.0, ANNULUS), (s_lo, rt, rs, -1.0, ANNULUS),
                                   (z_hi, 0.0, rt, 1.0, CAP), (z_lo, 0.0, rt, -1.0, CAP)):
        with np.errstate(invalid="ignore", divide="ignore"):
            s = (zp - o[2]) / d[:, 2]
        px, py = o[0] + s * d[:, 0], o[1] + s * d[:, 1]
        rr = px**2 + py**2
        hit = np.isfinite(s) & (s > 0) & (rr >= rin**2) & (rr <= rout**2) & (s < best) & (d[:, 2] * nz < 0)
        best[hit] = s[hit]
        label[hit] = lab
        nrm[hit] = [0.0, 0.0, nz]
    sl = label == SLEEVE0
    if sl.any():
        p = o[None, :] + best[sl, None] * d[sl]
        ang = np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * math.pi)
        k = np.minimum((ang / marker.beta).astype(np.int64), marker.columns - 1)
        row = np.where(np.abs(p[:, 2]) < marker.row_height, (p[:, 2] < 0).astype(np.int64), 2)
        label[sl] = SLEEVE0 + 2 * (row * marker.columns + k) + marker.dark(ang, p[:, 2])
    X = np.where(np.isfinite(best)[:, None], o[None, :] + np.where(np.isfinite(best), best, 0)[:, None] * d, 0)
    cosg = -np.sum(nrm * d, axis=1)
    return label, X @ Rm.T + t, nrm @ Rm.T, cosg


def materials(label: np.ndarray, marker: Marker, look: Look) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Albedo (N, 3), specular weight (N,) and shininess (N,) per label."""
    alb = np.zeros((len(label), 3))
    ks = np.zeros(len(label))
    shin = np.ones(len(label))
    for lab, col, k_s, sh in ((TUBE, look.tube, look.spec_tube, look.shin_tube),
                              (CAP, look.cap, look.spec_tube, look.shin_tube),
                              (ANNULUS, look.annulus, look.spec_sleeve, look.shin_sleeve)):
        m = label == lab
        alb[m], ks[m], shin[m] = col, k_s, sh
    sl = label >= SLEEVE0
    dark = (label[sl] - SLEEVE0) % 2 == 1  # as traced (Marker.dark)
    alb[sl] = np.where(dark[:, None], np.array(look.black)[None, :], np.array(look.white)[None, :])
    ks[sl], shin[sl] = look.spec_sleeve, look.shin_sleeve
    return alb, ks, shin


def object_roi(rig: Rig, eye: Eye, Rm: np.ndarray, t: np.ndarray, marker: Marker, look: Look,
               ) -> tuple[int, int, int, int] | None:
    """Pixel bounding box (x0, y0, x1, y1), inclusive, of the tube and sleeve in this eye, or None."""
    ang = np.linspace(0, 2 * math.pi, 48, endpoint=False)
    zs = np.linspace(marker.z_range[0] - (look.tube_proximal if look.body else 0.0), marker.tip_offset, 80)
    A, Z = np.meshgrid(ang, zs)
    P = np.stack([marker.radius * np.cos(A), marker.radius * np.sin(A), Z], axis=-1).reshape(-1, 3)
    X = t + P @ Rm.T
    Xe = X @ eye.R.T + eye.T
    X = X[Xe[:, 2] > 0.005]
    if not len(X):
        return None
    uv = project(eye, X)
    w, h = rig.size
    x0, y0 = np.floor(uv.min(axis=0)).astype(int) - 4
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 4
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w - 1), min(y1, h - 1)
    if x0 > x1 or y0 > y1:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear samples (N, C) of an (H, W, C) image at pixel positions uv (N, 2), pixel centres at integers."""
    h, w = img.shape[:2]
    u = np.clip(uv[:, 0], 0, w - 1.000001)
    v = np.clip(uv[:, 1], 0, h - 1.000001)
    iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = (u - iu)[:, None], (v - iv)[:, None]
    return ((1 - fu) * (1 - fv) * img[iv, iu] + fu * (1 - fv) * img[iv, iu + 1]
            + (1 - fu) * fv * img[iv + 1, iu] + fu * fv * img[iv + 1, iu + 1])


def render_eye(rig: Rig, eye: Eye, pix_dirs: np.ndarray, Rm: np.ndarray, t: np.ndarray, marker: Marker, look: Look,
               bg: Background, tex: np.ndarray) -> np.ndarray:
    """Linear radiance image (H, W, 3) float32 of one eye (before optics and sensor)."""
    w, h = rig.size
    B = background_radiance(rig, eye, pix_dirs, bg, tex, look.d_ref)
    roi = object_roi(rig, eye, Rm, t, marker, look)
    if roi is None:
        return B
    x0, y0, x1, y1 = roi
    W, H = x1 - x0 + 1, y1 - y0 + 1
    c = eye.centre

    def radiance(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lab, X, n, cosg = trace(rays(eye, uv), c, Rm, t, marker, look)
        out = np.zeros((len(uv), 3))
        fg = lab != BG
        if fg.any():
            alb, ks, shin = materials(lab[fg], marker, look)
            out[fg] = shade(n[fg], X[fg], c, rig.light, alb, ks, shin, look.d_ref)
        if (~fg).any():
            out[~fg] = bilinear(B, uv[~fg])
        return lab, out, cosg

    # pixel corners: pixel (u, v) covers [u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]
    ug, vg = np.meshgrid(np.arange(x0, x1 + 2, dtype=float) - 0.5, np.arange(y0, y1 + 2, dtype=float) - 0.5)
    lab_g, rad_g, cos_g = radiance(np.stack([ug.ravel(), vg.ravel()], axis=1))
    lab_g = lab_g.reshape(H + 1, W + 1)
    rad_g = rad_g.reshape(H + 1, W + 1, 3)
    graze = ((lab_g >= SLEEVE0) & (cos_g.reshape(H + 1, W + 1) < 0.35))
    c4 = (lab_g[:-1, :-1], lab_g[:-1, 1:], lab_g[1:, :-1], lab_g[1:, 1:])
    mixed = (c4[0] != c4[1]) | (c4[0] != c4[2]) | (c4[0] != c4[3])
    mixed |= graze[:-1, :-1] | graze[:-1, 1:] | graze[1:, :-1] | graze[1:, 1:]
    # uniform pixels: mean of the four corner samples (2 x 2 box); mixed pixels: S x S box
    img = 0.25 * (rad_g[:-1, :-1] + rad_g[:-1, 1:] + rad_g[1:, :-1] + rad_g[1:, 1:])
    yy, xx = np.nonzero(mixed)
    if len(yy):
        S = look.supersample
        offs = (np.arange(S) + 0.5) / S - 0.5
        ox, oy = np.meshgrid(offs, offs)
        su = (xx[:, None] + x0 + ox.ravel()[None, :]).ravel()
        sv = (yy[:, None] + y0 + oy.ravel()[None, :]).ravel()
        rad_s = radiance(np.stack([su, sv], axis=1))[1].reshape(len(yy), S * S, 3).mean(axis=1)
        img[yy, xx] = rad_s
    out = B.copy()
    out[y0:y1 + 1, x0:x1 + 1] = img.astype(np.float32)
    return out


@functools.lru_cache(maxsize=4)
def vignette(w: int, h: int, strength: float) -> np.ndarray:
    """Relative illumination (H, W) float32: 1 at the centre, 1 - strength at the image corners."""
    xx = (np.arange(w, dtype=np.float32) - (w - 1) / 2) / (w / 2)
    yy = (np.arange(h, dtype=np.float32) - (h - 1) / 2) / (h / 2)
    return (1 - strength * 0.5 * (xx[None, :] ** 2 + yy[:, None] ** 2)).astype(np.float32)


def sensor(rad: np.ndarray, rng: np.random.Generator, look: Look, exposure: float) -> np.ndarray:
    """Optics blur, vignetting, gamma, shot + read noise and 8-bit quantisation: uint8 BGR (or grey)."""
    h, w = rad.shape[:2]
    img = cv2.GaussianBlur(rad, (0, 0), look.blur_sigma) if look.blur_sigma > 0 else rad
    img = img * (vignette(w, h, look.vignette) * np.float32(exposure))[:, :, None]
    if look.gray:
        img = img @ np.array([0.114, 0.587, 0.299], np.float32)
        img = img[:, :, None]
    signal = 255.0 * np.clip(img, 0, 1) ** (1 / look.gamma)
    sd = np.sqrt(look.shot_gain * signal + look.read_noise**2)
    noisy = signal + sd * rng.standard_normal(signal.shape, dtype=np.float32)
    out = np.clip(np.round(noisy), 0, 255).astype(np.uint8)
    if look.gray:
        out = out[:, :, 0]
    if look.jpeg:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(look.jpeg)])
        assert ok
        out = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return out


# ----------------------------------------------------------------------------------------------------------
# dataset


def write_calib(path: Path, rig: Rig) -> None:
    """calib.yaml in docs/design.md's format (SI; no world_T_left)."""
    data = {
        "image_size": [int(rig.size[0]), int(rig.size[1])],
        "left": {"K": rig.left.K.tolist(), "dist": rig.left.dist.tolist()},
        "right": {"K": rig.right.K.tolist(), "dist": rig.right.dist.tolist()},
        "R": rig.right.R.tolist(),
        "T": rig.right.T.tolist(),
    }
    path.write_text(yaml.safe_dump(data, default_flow_style=None, sort_keys=False))


def read_marker(path: Path) -> Marker:
    """Marker from a marker.yaml (radius, columns, row_height, tip_offset [m], optional patches)."""
    d = yaml.safe_load(path.read_text())
    patches = tuple(tuple(float(v) for v in p) for p in d.get("patches", []))
    return Marker(float(d["radius"]), int(d["columns"]), float(d["row_height"]), float(d["tip_offset"]),
                  patches)  # type: ignore[arg-type]


def truth_entry(n: int, rig: Rig, marker: Marker, Rm: np.ndarray, t: np.ndarray) -> dict[str, Any]:
    """truth.json object of pair n: pose of {wm} in {ll}, tip in {ll}, per-corner raw uv and cos_view."""
    X = t + marker.corners() @ Rm.T
    a = marker.beta * np.arange(marker.columns)
    N = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1) @ Rm.T
    entry: dict[str, Any] = {"pair": n, "R": Rm.tolist(), "t": t.tolist(),
                             "tip": (t + Rm[:, 2] * marker.tip_offset).tolist()}
    for side, eye in (("left", rig.left), ("right", rig.right)):
        uv = project(eye, X)
        cv = cos_view(eye, X, N)
        entry[f"corners_{side}"] = [{"index": i, "uv": [float(uv[i, 0]), float(uv[i, 1])], "cos_view": float(cv[i])}
                                    for i in range(marker.columns)]
    return entry


def pixel_rays(rig: Rig, eye: Eye, step: int = 4) -> np.ndarray:
    """Unit rays in {ll} of every pixel centre, shape (H*W, 3), for the background: exact rays
    (cv2.undistortPoints) on every ``step``-th pixel position, bilinearly interpolated in between."""
    w, h = rig.size
    gw, gh = -(-w // step) + 1, -(-h // step) + 1
    gu, gv = np.meshgrid(np.arange(gw) * step + (step - 1) / 2, np.arange(gh) * step + (step - 1) / 2)
    n = cv2.undistortPoints(np.stack([gu.ravel(), gv.ravel()], 1).reshape(-1, 1, 2).astype(np.float64), eye.K,
                            eye.dist, criteria=UNDISTORT_CRITERIA).reshape(gh, gw, 2).astype(np.float32)
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    m = cv2.remap(n, (u - (step - 1) / 2) / step, (v - (step - 1) / 2) / step, cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE).reshape(-1, 2).astype(np.float64)
    d = np.concatenate([m, np.ones((len(m), 1))], axis=1) @ eye.R
    return d / np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]


def render_dataset(out: str | Path, pairs: int = 5, seed: int = 0, scale: float = 1.0, marker: Marker | None = None,
                   look: Look | None = None, marker_file: str | Path | None = None,
                   poses: list[tuple[np.ndarray, np.ndarray]] | None = None) -> dict[str, Any]:
    """Write a dataset (calib.yaml, marker.yaml, pair_NN_left/right.png, truth.json) to ``out``.

    ``marker_file``: a marker.yaml to render (and copy), instead of ``marker``; ``poses``: the poses
    (R, t) of {wm} in {ll} to render (``pairs`` is then their number), instead of random ones.
    Returns a summary: folder, pairs, seed, image size, render seconds per pair."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    marker = read_marker(Path(marker_file)) if marker_file is not None else (marker or Marker())
    pairs = len(poses) if poses is not None else pairs
    look = look or Look()
    rng = np.random.default_rng(seed)
    rig = random_rig(rng, scale)
    write_calib(out / "calib.yaml", rig)
    mk: dict[str, Any] = {"radius": marker.radius, "columns": marker.columns, "row_height": marker.row_height,
                          "tip_offset": marker.tip_offset}
    if marker.patches:
        mk["patches"] = [list(p) for p in marker.patches]
    (out / "marker.yaml").write_text(yaml.safe_dump(mk, sort_keys=False))
    if marker_file is not None:  # the marker file as given (decoder keys included)
        (out / "marker.yaml").write_text(Path(marker_file).read_text())
    marker = read_marker(out / "marker.yaml")  # render what the file says
    tex = make_texture(rng)
    dirs = {"left": pixel_rays(rig, rig.left), "right": pixel_rays(rig, rig.right)}
    truth = []
    t0 = time.perf_counter()
    for n in range(pairs):
        Rm, t = random_pose(rng, rig, marker, look) if poses is None else poses[n]
        bg = random_background(rng, t, tex.shape[0])
        exposure = rng.uniform(0.8, 1.15)
        if look.auto_exposure:  # the endoscope's exposure control levels the marker's distance fall-off
            exposure *= (float(np.linalg.norm(t - rig.light)) / look.d_ref) ** 2
        for side, eye in (("left", rig.left), ("right", rig.right)):
            rad = render_eye(rig, eye, dirs[side], Rm, t, marker, look, bg, tex)
            img = sensor(rad, rng, look, exposure)
            cv2.imwrite(str(out / f"pair_{n:02d}_{side}.png"), img)
        truth.append(truth_entry(n, rig, marker, Rm, t))
    (out / "truth.json").write_text(json.dumps(truth, indent=1))
    dt = time.perf_counter() - t0
    return {"out": str(out), "pairs": pairs, "seed": seed, "image_size": list(rig.size), "columns": marker.columns,
            "s_per_pair": dt / max(pairs, 1)}


def glare_look(jpeg: int | None = None, gray: bool = False, direction: str = "right") -> Look:
    """Stress look: fixed exposure (whites saturate at 60 mm) and a strong, broad sheen on the sleeve."""
    return Look(jpeg=jpeg, gray=gray, direction=direction, auto_exposure=False, spec_sleeve=0.25, shin_sleeve=30.0)


def main(argv: list[str] | None = None) -> int:
    """Command line of the independent renderer; prints a JSON summary."""
    p = argparse.ArgumentParser(description="independent stereo renderer of the wrist marker (docs/design.md format)")
    p.add_argument("--out", required=True)
    p.add_argument("--pairs", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scale", type=float, default=1.0, help="image scale (1: 1920x1080)")
    p.add_argument("--columns", type=int, default=12)
    p.add_argument("--radius", type=float, default=0.00455, help="sleeve radius [m]")
    p.add_argument("--jpeg", type=int, default=None, help="JPEG round trip at this quality")
    p.add_argument("--gray", action="store_true", help="write grey images instead of BGR")
    p.add_argument("--direction", choices=["right", "left", "random"], default="right",
                   help="direction of the tip in the image")
    p.add_argument("--glare", action="store_true",
                   help="no exposure control and a strong, broad specular lobe (saturated whites up close)")
    p.add_argument("--no-body", action="store_true", help="no tube behind (proximal to) the sleeve")
    p.add_argument("--marker-file", default=None, help="render this marker.yaml (patches included)")
    a = p.parse_args(argv)
    look = glare_look(a.jpeg, a.gray, a.direction) if a.glare else Look(jpeg=a.jpeg, gray=a.gray, direction=a.direction)
    look.body = not a.no_body
    summary = render_dataset(a.out, a.pairs, a.seed, a.scale, Marker(radius=a.radius, columns=a.columns), look,
                             a.marker_file)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
