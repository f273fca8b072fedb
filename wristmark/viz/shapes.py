"""Meshcat geometry that the URDF does not give: the marker's checker sleeve, the endoscope with
its two view frustums, the floor grid and the trail lines. Frames: {w} world, {wm} marker,
{ll} left camera; metres.
"""

from __future__ import annotations

from typing import Any

import meshcat.geometry as mg
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.models.marker import MarkerModel
from wristmark.viz.style import ENDOSCOPE_COLOR, MARKER_BLACK, MARKER_WHITE, RGB, hex_color

Array = NDArray[np.float64]
Points32 = NDArray[np.float32]  # Meshcat geometry buffers

ENDOSCOPE_RADIUS = 0.005  # [m] shaft of a 10 mm stereo endoscope
ENDOSCOPE_LENGTH = 0.06  # [m] drawn length of the shaft behind the lenses
FRUSTUM_DEPTH = 0.085  # [m] along the optical axis; the workspace centre is ~0.08 m ahead

# Meshcat cylinders lie along y; this turns them to lie along z.
Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])


class NormalMeshGeometry(mg.TriangularMeshGeometry):  # type: ignore[misc]
    """Triangle mesh with explicit vertex normals, so Phong/Lambert materials shade it."""

    def __init__(self, vertices: Array, faces: NDArray[np.int64], normals: Array) -> None:
        super().__init__(vertices, faces)
        self.normals = np.asarray(normals, dtype=np.float32)

    def lower(self, object_data: Any) -> dict[str, Any]:
        out: dict[str, Any] = super().lower(object_data)
        out["data"]["attributes"]["normal"] = mg.pack_numpy_array(self.normals.T)
        return out


def checker_sleeve(marker: MarkerModel, steps_per_patch: int = 4) -> tuple[NormalMeshGeometry, NormalMeshGeometry]:
    """(black, white) meshes of the sleeve in {wm}: two rows of ``marker.columns`` patches,
    column k spanning [k beta, (k+1) beta) from x_wm towards y_wm, upper row black for even k."""
    r, h, beta = marker.radius, marker.row_height, marker.beta
    parts: dict[bool, tuple[list[Array], list[NDArray[Any]], list[Array]]] = {True: ([], [], []), False: ([], [], [])}
    for k in range(marker.columns):
        a = k * beta + beta * np.arange(steps_per_patch + 1) / steps_per_patch
        ring = np.column_stack([np.cos(a), np.sin(a)])
        for z0, z1 in ((0.0, h), (-h, 0.0)):
            black = marker.is_black((k + 0.5) * beta, (z0 + z1) / 2.0)
            verts, faces, normals = parts[black]
            base = sum(len(v) for v in verts)
            n = len(a)
            v = np.vstack([np.column_stack([r * ring, np.full(n, z0)]), np.column_stack([r * ring, np.full(n, z1)])])
            nr = np.vstack([np.column_stack([ring, np.zeros(n)])] * 2)
            i = np.arange(n - 1)
            f = np.vstack([np.column_stack([i, i + 1, i + n]), np.column_stack([i + 1, i + n + 1, i + n])]) + base
            verts.append(v)
            faces.append(f)
            normals.append(nr)
    out = []
    for black in (True, False):
        verts, faces, normals = parts[black]
        out.append(NormalMeshGeometry(np.vstack(verts), np.vstack(faces), np.vstack(normals)))
    return out[0], out[1]


def sleeve_materials() -> tuple[mg.Material, mg.Material]:
    """Materials of the black and white patches (slightly shaded, never glossy)."""
    return (
        mg.MeshLambertMaterial(color=hex_color(MARKER_BLACK)),
        mg.MeshLambertMaterial(color=hex_color(MARKER_WHITE)),
    )


def world_T_right(camera: StereoCamera) -> Array:
    """Pose of the right camera in {w} from X_right = R X_left + T and world_T_left."""
    if camera.T_world_left is None:
        raise ValueError("the camera has no world_T_left")
    T_right_left = np.eye(4)
    T_right_left[:3, :3] = np.asarray(camera.R, float)
    T_right_left[:3, 3] = np.asarray(camera.T, float)
    return np.asarray(camera.T_world_left, float) @ np.linalg.inv(T_right_left)


def frustum_lines(K: Array, image_size: tuple[int, int], depth: float = FRUSTUM_DEPTH) -> Points32:
    """Segment end points (3, 16) in the camera's own frame: 4 edges from the optical centre to
    the image corners back-projected to ``depth`` [m] (pinhole, distortion ignored) + the
    rectangle at that depth. Meshcat LineSegments take points as columns."""
    w, h = image_size
    Kinv = np.linalg.inv(np.asarray(K, float))
    px = np.array([[-0.5, -0.5, 1.0], [w - 0.5, -0.5, 1.0], [w - 0.5, h - 0.5, 1.0], [-0.5, h - 0.5, 1.0]])
    rays = px @ Kinv.T
    corners = depth * rays / rays[:, 2:3]
    segs = []
    for i in range(4):
        segs += [np.zeros(3), corners[i], corners[i], corners[(i + 1) % 4]]
    return np.array(segs, dtype=np.float32).T


def line_segments(points_cols: NDArray[Any], color: RGB, linewidth: float = 2.0) -> mg.LineSegments:
    """Meshcat LineSegments of (3, 2k) points in one colour."""
    return mg.LineSegments(mg.PointsGeometry(np.asarray(points_cols, np.float32)),
                           mg.LineBasicMaterial(color=hex_color(color), linewidth=linewidth))


def polyline(points: Array, color: RGB, opacity: float = 1.0, linewidth: float = 2.0) -> mg.Line:
    """Meshcat Line through (N, 3) points [m]."""
    P = np.asarray(points, np.float32).reshape(-1, 3)
    if len(P) < 2:
        P = np.vstack([P, P]) if len(P) else np.zeros((2, 3), np.float32)
    mat = mg.LineBasicMaterial(color=hex_color(color), linewidth=linewidth, opacity=opacity,
                               transparent=opacity < 1.0)
    return mg.Line(mg.PointsGeometry(P.T), mat)


def endoscope_shaft() -> tuple[mg.Cylinder, mg.Material, Array]:
    """(geometry, material, pose in {ll}) of the endoscope's shaft: a cylinder along -z_ll that
    ends at the lenses (between the two optical centres)."""
    T = np.eye(4)
    T[2, 3] = -ENDOSCOPE_LENGTH / 2.0 - 0.001
    return (mg.Cylinder(ENDOSCOPE_LENGTH, ENDOSCOPE_RADIUS),
            mg.MeshPhongMaterial(color=hex_color(ENDOSCOPE_COLOR), reflectivity=0.3), T @ Y_TO_Z)


def floor_grid(centre_xy: tuple[float, float] = (0.04, 0.0), half: float = 0.08, step: float = 0.01) -> Points32:
    """Segment end points (3, 2k) of a square grid in the incision plane z_w = 0 [m] (1 cm cells
    by default): a scale cue at the arm's size."""
    cx, cy = centre_xy
    ticks = np.arange(-half, half + step / 2, step)
    segs = []
    for v in ticks:
        segs += [[cx + v, cy - half, 0.0], [cx + v, cy + half, 0.0], [cx - half, cy + v, 0.0], [cx + half, cy + v, 0.0]]
    return np.array(segs, dtype=np.float32).T


def translation(p: Array) -> Array:
    """4x4 pure translation by p [m]."""
    T = np.eye(4)
    T[:3, 3] = np.asarray(p, float)
    return T

