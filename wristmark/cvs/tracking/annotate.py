"""Frames for a person to look at: the detected corners with their marker indices, the marker
axes of the tracked pose projected through the camera model, and the tracking status.

``annotate_pair`` draws on copies of both views and returns them side by side;
``AnnotationWriter`` writes annotated frames to a folder (``frame_NNNNNN.png``) or a video
(.mp4: mp4v, .avi and .mkv: MJPG).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.tracking.tracker import TrackResult
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]
VIDEO_FOURCC = {".mp4": "mp4v", ".avi": "MJPG", ".mkv": "MJPG"}
_AXES_BGR = ((0, 0, 255), (0, 200, 0), (255, 80, 0))  # x red, y green, z blue
_OK_BGR, _REJECTED_BGR, _TIP_BGR = (0, 255, 255), (0, 0, 255), (255, 0, 255)


def _bgr(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy())


def _pt(uv: Array) -> tuple[int, int]:
    return int(round(float(uv[0]))), int(round(float(uv[1])))


def _draw_view(img: NDArray[np.uint8], corners: Array, indices: NDArray[np.int_] | None,
               axes_uv: Array | None, scale: float) -> None:
    r, th = max(int(4 * scale), 2), max(int(round(scale)), 1)
    font = 0.45 * scale
    if axes_uv is not None and np.all(np.isfinite(axes_uv)):  # axes first: the corners stay on top
        origin = _pt(axes_uv[0])
        for a in range(3):
            cv2.arrowedLine(img, origin, _pt(axes_uv[a + 1]), _AXES_BGR[a], 2 * th, cv2.LINE_AA, tipLength=0.15)
        cv2.drawMarker(img, _pt(axes_uv[4]), _TIP_BGR, cv2.MARKER_CROSS, 4 * r, th, cv2.LINE_AA)
    for k, uv in enumerate(np.asarray(corners, float).reshape(-1, 2)):
        i = -1 if indices is None or k >= len(indices) else int(indices[k])
        colour = _OK_BGR if i >= 0 else _REJECTED_BGR
        cv2.circle(img, _pt(uv), r, colour, th, cv2.LINE_AA)
        label, at = (str(i) if i >= 0 else "x"), _pt(uv + [-4 * r - 2, r])  # left of the corner
        cv2.putText(img, label, at, cv2.FONT_HERSHEY_SIMPLEX, font, (0, 0, 0), 3 * th, cv2.LINE_AA)
        cv2.putText(img, label, at, cv2.FONT_HERSHEY_SIMPLEX, font, colour, th, cv2.LINE_AA)


def marker_axes_left(T_left_marker: Array, marker: MarkerModel, length: float | None = None) -> Array:
    """Points in {ll} [m]: {wm}'s origin, the ends of its x, y, z axes (``length`` [m], default
    2 radii) and the tip."""
    L = 2.0 * marker.radius if length is None else float(length)
    P = np.vstack([np.zeros(3), L * np.eye(3), marker.tip()])
    return P @ T_left_marker[:3, :3].T + T_left_marker[:3, 3]


def annotate_pair(left: NDArray[np.uint8], right: NDArray[np.uint8], result: TrackResult,
                  camera: StereoCamera, marker: MarkerModel) -> NDArray[np.uint8]:
    """Both views (BGR copies) with corners, indices, axes and status, side by side."""
    views = [_bgr(left), _bgr(right)]
    scale = max(views[0].shape[1] / 960.0, 0.6)
    axes: list[Array | None] = [None, None]
    if result.ok and result.T_left_marker is not None:
        P = marker_axes_left(result.T_left_marker, marker)
        axes = [camera.project_left(P), camera.project_right(P)]
    m = result.match
    idx = (None, None) if m is None else (m.index_left, m.index_right)
    for v, corners, ind, ax in zip(views, (result.corners_left, result.corners_right), idx, axes):
        _draw_view(v, corners, ind, ax, scale)
    if result.ok:
        text = f"ok  rms {result.rms_px:.2f} px  {result.time_ms:.1f} ms"
        if result.tip_left is not None:
            x, y, z = (1e3 * result.tip_left).tolist()
            text += f"  tip [{x:.1f}, {y:.1f}, {z:.1f}] mm"
    else:
        text = f"no pose: {result.reason}"
    cv2.putText(views[0], text, (int(8 * scale), views[0].shape[0] - int(10 * scale)), cv2.FONT_HERSHEY_SIMPLEX,
                0.5 * scale, (255, 255, 255), max(int(round(scale)), 1), cv2.LINE_AA)
    return np.ascontiguousarray(np.concatenate(views, axis=1))


class AnnotationWriter:
    """Writes annotated frames to a folder (PNG per frame) or a video file (by suffix)."""

    def __init__(self, target: str | Path, fps: float = 30.0) -> None:
        self.target, self.fps = Path(target), float(fps) if fps and fps > 0 else 30.0
        self._video: cv2.VideoWriter | None = None
        self.written = 0
        suffix = self.target.suffix.lower()
        self.is_video = suffix in VIDEO_FOURCC
        if self.is_video:
            if not self.target.parent.is_dir():
                raise InputError(f"{self.target.parent}: folder for the annotated video does not exist")
        elif suffix:
            raise InputError(f"--annotate {self.target}: a folder or a .mp4, .avi or .mkv file")
        else:
            self.target.mkdir(parents=True, exist_ok=True)

    def write(self, image: NDArray[np.uint8], index: int) -> None:
        """Add one annotated frame (``index`` names the PNG in a folder)."""
        if not self.is_video:
            path = self.target / f"frame_{index:06d}.png"
            if not cv2.imwrite(str(path), image):
                raise InputError(f"{path}: cannot write the annotated frame")
        else:
            if self._video is None:
                h, w = image.shape[:2]
                fourcc = cv2.VideoWriter.fourcc(*VIDEO_FOURCC[self.target.suffix.lower()])
                self._video = cv2.VideoWriter(str(self.target), fourcc, self.fps, (w, h))
                if not self._video.isOpened():
                    raise InputError(f"{self.target}: cannot open a video writer")
            self._video.write(image)
        self.written += 1

    def close(self) -> None:
        """Finish the video (idempotent)."""
        if self._video is not None:
            self._video.release()
            self._video = None
