"""Which of a sleeve's corners another arm's edges may reach (cvs.tracking.arm_set leaves them out
of the pose): :func:`outlines`, :func:`reached`.

A corner's sub-pixel fit takes in what its window holds; another arm's edge there pulls it off by
less than the pose solve's outlier test sees (docs/notes/several-arms.md). A corner is reached
(a) within ``r`` of the outline of another arm found in the pair and nearer the camera there, or
(b) when its disc of radius ``r`` holds, outside its own arm's outline, an edge at least
``edge_ratio`` times the strongest inside it (an arm that is not found).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.gray_image import to_gray
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]

__all__ = ["Outline", "foreign_edge", "outlines", "reached"]


class Outline(NamedTuple):
    """An arm's body in one view: its outline (convex hull [px], float32 for
    cv2.pointPolygonTest), its axis's pixels (n, 2) and their depths (n,) [m]."""

    hull: NDArray[np.float32]
    axis_px: Array
    axis_depth: Array


_RING = 16  # outline points per end ring


@lru_cache(maxsize=16)
def _body_points(radius: float, z_lo: float, z_hi: float) -> Array:
    """The cylinder's end rings (2 x ``_RING`` points) and 5 points of its axis, in {wm} [m]."""
    ang = np.linspace(0.0, 2.0 * np.pi, _RING + 1)[:-1]
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)]) * radius
    zs = np.linspace(z_lo, z_hi, 5)
    pts = np.vstack([ring + [0.0, 0.0, z] for z in (z_lo, z_hi)] + [np.column_stack([0 * zs, 0 * zs, zs])])
    pts.setflags(write=False)
    return pts


def outlines(camera: StereoCamera, marker: MarkerModel, poses: Mapping[str, Array], z_lo: float, z_hi: float
             ) -> dict[str, list[Outline | None]]:
    """Per arm (pose of {wm} in {ll} [m]) and view (left, right): the outline of the cylinder of
    the sleeve's radius from z_lo to z_hi along z_wm [m]; None where it is behind the camera.
    Every arm's points are projected in one call per view (the same pixels as one call each)."""
    pts = _body_points(float(marker.radius), float(z_lo), float(z_hi))
    n, m = pts.shape[0], 2 * _RING
    R, T = np.asarray(camera.R, float).T, np.asarray(camera.T, float).reshape(3)
    per_view: list[list[Array]] = [[], []]
    for T_lm in poses.values():
        P_left = pts @ T_lm[:3, :3].T + T_lm[:3, 3]
        per_view[0].append(P_left)
        per_view[1].append(P_left @ R + T)
    out: dict[str, list[Outline | None]] = {a: [] for a in poses}
    for cam, Ps in ((camera.left, per_view[0]), (camera.right, per_view[1])):
        front = [bool(np.all(P[:, 2] > 1e-3)) for P in Ps]
        shown = [P for P, f in zip(Ps, front) if f]
        uv_all = cam.project(np.vstack(shown)) if shown else np.zeros((0, 2))
        k = 0
        for a, P, f in zip(poses, Ps, front):
            if not f:
                out[a].append(None)
                continue
            uv = uv_all[k * n:(k + 1) * n]
            k += 1
            hull = np.asarray(cv2.convexHull(uv[:m].astype(np.float32)), np.float32)
            out[a].append(Outline(hull, uv[m:], np.asarray(P[m:, 2], float)))
    return out


@lru_cache(maxsize=8)
def _masks(R: int, radius: float, margin_px: int) -> tuple[NDArray[np.bool_], NDArray[np.uint8]]:
    """The disc of ``radius`` in a (2 R + 1)^2 patch, and the structuring element growing the outline."""
    yy, xx = np.mgrid[-R:R + 1, -R:R + 1]
    disc = xx ** 2 + yy ** 2 <= radius ** 2
    disc.setflags(write=False)
    return disc, np.asarray(cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1,) * 2), np.uint8)


def foreign_edge(img: NDArray[np.uint8], corner: Array, own: NDArray[np.float32], radius: float, ratio: float,
                 margin_px: int = 2) -> bool:
    """Whether the disc of ``radius`` [px] around ``corner`` holds an edge outside the arm's own
    outline ``own`` (grown by ``margin_px``: its silhouette's own blurred edge) whose gradient is
    at least ``ratio`` times the strongest inside it. Alone, what borders a sleeve is smooth
    tissue; an edge there is another arm's (found or not)."""
    R = int(np.ceil(radius)) + 2
    u, v = int(round(float(corner[0]))), int(round(float(corner[1])))
    h, w = img.shape[:2]
    if u - R < 0 or v - R < 0 or u + R >= w or v + R >= h:
        return False
    patch = to_gray(np.ascontiguousarray(img[v - R:v + R + 1, u - R:u + R + 1])).astype(np.float32)
    g = cv2.GaussianBlur(patch, (0, 0), 1.0)
    mag = np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1))
    inside = np.zeros(patch.shape, np.uint8)
    cv2.fillConvexPoly(inside, np.round(own.reshape(-1, 2) - [u - R, v - R]).astype(np.int32), 1)
    disc, kernel = _masks(R, float(radius), int(margin_px))
    grown = cv2.dilate(inside, kernel)
    outside, within = disc & (grown == 0), disc & (inside > 0)
    return bool(outside.any() and within.any() and mag[outside].max() > ratio * mag[within].max())


def _nearest_depth(line: Outline, corners: Array) -> Array:
    """Per corner, the depth [m] of the axis pixel nearest it."""
    d = line.axis_px[None, :, :] - corners[:, None, :]
    return line.axis_depth[np.argmin(np.hypot(d[..., 0], d[..., 1]), axis=1)]


def reached(img: NDArray[np.uint8], corners: Array, own: Outline, others: Sequence[Outline], r: float,
            edge_ratio: float) -> NDArray[np.bool_]:
    """Per corner (n, 2) [px] of an arm in one view: whether another arm's edges may reach it
    (module doc: (a) an outline in ``others`` within ``r`` and nearer the camera, (b)
    :func:`foreign_edge` in ``img``). Only corners within ``r`` (plus a pixel) of another
    outline's bounding box are tested against it, and only those within ``r`` of their own
    outline's border for (b): a window wholly inside the outline holds nothing outside it."""
    c = np.asarray(corners, float).reshape(-1, 2)
    out = np.zeros(c.shape[0], bool)
    if c.shape[0] == 0:
        return out
    z_own: Array | None = None
    for other in others:
        box = other.hull.reshape(-1, 2)
        gap = np.maximum(np.maximum(box.min(axis=0) - c, c - box.max(axis=0)), 0.0)
        near = np.flatnonzero(np.hypot(gap[:, 0], gap[:, 1]) < r + 1.0)
        if near.size == 0:
            continue
        z_own = _nearest_depth(own, c) if z_own is None else z_own
        z_other = _nearest_depth(other, c[near])
        for j, i in enumerate(near):
            if cv2.pointPolygonTest(other.hull, (float(c[i, 0]), float(c[i, 1])), True) > -r and z_other[j] < z_own[i]:
                out[i] = True
    for i in np.flatnonzero(~out):
        if cv2.pointPolygonTest(own.hull, (float(c[i, 0]), float(c[i, 1])), True) < r and \
                foreign_edge(img, c[i], own.hull, r, edge_ratio):
            out[i] = True
    return out
