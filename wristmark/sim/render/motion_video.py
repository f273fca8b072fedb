"""A rendered stereo video of the marked arm in smooth motion: test and benchmark material for
the video frame sources (a real file written by ``cv2.VideoWriter``, read back by FFmpeg).

``motion_psi(n)`` is a slow closed loop in configuration space around HOME_PSI (stem turn,
feed and both bending planes: the marker moves and turns in view); ``render_motion`` renders it
(ground truth kept); ``write_stereo_video`` writes the pairs side by side (or top-bottom) as
MJPG (.avi, quality 95) or lossless FFV1 (.mkv).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.cvs.sources.layout import join_stereo
from wristmark.models.arm_shape import arm_shape
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer

Array = NDArray[np.float64]
# Amplitudes of the loop around HOME_PSI: phi [rad], d [m], theta1, delta1, theta2, delta2 [rad].
MOTION_AMPLITUDE = (0.12, 0.004, 0.06, 0.25, 0.10, 0.30)
FOURCC_BY_SUFFIX = {".avi": "MJPG", ".mkv": "FFV1"}


def motion_psi(n: int, cycles: float = 1.0) -> list[Array]:
    """``n`` configurations along ``cycles`` turns of a smooth loop around HOME_PSI."""
    home, amp = np.asarray(HOME_PSI, float), np.asarray(MOTION_AMPLITUDE, float)
    out = []
    for k in range(n):
        a = 2 * np.pi * cycles * k / max(n, 1)
        wave = np.array([np.sin(a), np.sin(2 * a), np.sin(a + 1.0), np.cos(a), np.sin(a + 2.0), np.cos(2 * a)])
        out.append(home + amp * wave)
    return out


def render_motion(camera: StereoCamera, n: int, scale: float = 1.0, seed: int = 0, noise: str = "default",
                  marker: MarkerModel | None = None, params: RobotParams | None = None) -> list[RenderedPair]:
    """Render ``n`` pairs of :func:`motion_psi` with ``camera`` scaled by ``scale``."""
    cam = scaled_stereo_camera(camera, scale) if scale != 1.0 else camera
    marker, params = marker or MarkerModel(), params or RobotParams()
    renderer = StereoRenderer(cam, marker, noise_preset(noise), seed=seed)
    return [renderer.render(arm_shape(params, q)) for q in motion_psi(n)]


def write_stereo_video(path: str | Path, pairs: list[RenderedPair] | list[tuple[NDArray[np.uint8], NDArray[np.uint8]]],
                       fps: float, layout: str = "sbs", quality: int = 95) -> Path:
    """Write the pairs as one stereo video (codec by suffix: .avi MJPG, .mkv FFV1)."""
    p = Path(path)
    fourcc = FOURCC_BY_SUFFIX.get(p.suffix.lower())
    if fourcc is None:
        raise InputError(f"{p}: write a stereo video as .avi (MJPG) or .mkv (FFV1)")
    views = [(q.left, q.right) if isinstance(q, RenderedPair) else q for q in pairs]
    first = join_stereo(*views[0], layout=layout)
    h, w = first.shape[:2]
    vw = cv2.VideoWriter(str(p), cv2.VideoWriter.fourcc(*fourcc), float(fps), (w, h))
    if not vw.isOpened():
        raise InputError(f"{p}: cannot open a {fourcc} video writer")
    vw.set(cv2.VIDEOWRITER_PROP_QUALITY, int(quality))
    for left, right in views:
        frame = join_stereo(left, right, layout)
        vw.write(frame if frame.ndim == 3 else cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))
    vw.release()
    return p
