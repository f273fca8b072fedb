"""Turn a ``--source`` / ``--camera`` SPEC (docs/design.md "Stereo frame sources") into a
:class:`cvs.sources.frames.StereoSource`.

| SPEC | source |
|---|---|
| a list of paths LEFT RIGHT ... | image pairs (cvs.sources.images) |
| ``DIR`` (no ``metadata.yaml``) | a dataset folder, pair_NN_left.*, pair_NN_right.* |
| ``FILE.mcap``, ``FILE.db3``, ``BAGDIR`` (with ``metadata.yaml``) | a ROS 2 bag (cvs.sources.bag) |
| ``/dev/videoN``, ``device:N`` | a V4L2/UVC camera (cvs.sources.v4l2) |
| ``http://...``, ``rtsp://...`` | a network stream (cvs.sources.stream) |
| ``LEFT_FILE,RIGHT_FILE`` | two videos read together (cvs.sources.video) |
| any other file | one stereo video, ``layout`` sbs or tb |

With ``SourceOptions.image_size`` set (the calibration's), every frame is checked: a half of
another size is a one-line FrameSourceError naming both sizes. ``SourceOptions.grayscale``
hands out grey views.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from wristmark.cvs.gray_image import to_gray
from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame, StereoSource, check_frame_size
from wristmark.cvs.sources.layout import check_layout

DEFAULT_TOPICS = ("/stereo/left/image_raw", "/stereo/right/image_raw")
BAG_SUFFIXES = (".mcap", ".db3")


@dataclass(frozen=True)
class SourceOptions:
    """How to open a source. layout: 'sbs' | 'tb' (one frame holding both views); size: (width,
    height) of a camera's whole frame [px]; fps: camera frame rate to request [1/s]; fourcc:
    camera pixel format; topics: (left, right) image topics of a bag; timeout: a live source's
    open and stall timeout [s]; paced: play files and bags at their recorded rate in wall-clock
    time (video: newest-frame semantics, dropped frames counted); image_size: (width, height) of
    each view the calibration expects [px] (None: no check); grayscale: hand out 8-bit grey
    views (videos: MJPG decodes only its luma plane, 2-5x faster here; other sources convert)."""

    layout: str = "sbs"
    size: tuple[int, int] | None = None
    fps: float | None = None
    fourcc: str | None = "MJPG"
    topics: tuple[str, str] = DEFAULT_TOPICS
    timeout: float = 5.0
    paced: bool = False
    image_size: tuple[int, int] | None = None
    grayscale: bool = False

    def validate(self) -> None:
        """FrameSourceError naming the first bad option."""
        check_layout(self.layout)
        if self.size is not None and not (len(self.size) == 2 and all(int(v) > 0 for v in self.size)):
            raise FrameSourceError(f"size must be two positive pixel counts WxH, got {self.size}")
        if self.fps is not None and not (math.isfinite(self.fps) and self.fps > 0):
            raise FrameSourceError(f"fps must be > 0, got {self.fps}")
        if not (math.isfinite(self.timeout) and self.timeout > 0):
            raise FrameSourceError(f"timeout must be > 0 s, got {self.timeout}")
        if len(self.topics) != 2 or not all(t.startswith("/") for t in self.topics):
            raise FrameSourceError(f"topics must be two topic names LEFT,RIGHT starting with '/', got {self.topics}")


class CheckedSource:
    """A source whose every frame is checked against the calibration's image size (None: no
    check) and, with ``grayscale``, converted to grey where the source delivered BGR."""

    def __init__(self, source: StereoSource, image_size: tuple[int, int] | None, grayscale: bool = False) -> None:
        self.source, self.image_size, self.grayscale, self.name = source, image_size, grayscale, source.name

    def __len__(self) -> int:
        return source_length(self.source) or 0

    @property
    def dropped(self) -> int:
        return self.source.dropped

    def read(self) -> StereoFrame | None:
        frame = self.source.read()
        if frame is None:
            return None
        if self.image_size is not None:
            check_frame_size(frame, self.image_size, self.name)
        if self.grayscale and frame.left.ndim == 3:
            frame = replace(frame, left=to_gray(frame.left), right=to_gray(frame.right))
        return frame

    def close(self) -> None:
        self.source.close()

    def __getattr__(self, name: str) -> object:
        """Everything else is the wrapped source's (fps, decode_skipped, captured, ...)."""
        if name == "source":  # not set yet (e.g. during unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.source, name)


def source_length(source: StereoSource) -> int | None:
    """Frames a finite source will hand out (None for live or unknown)."""
    try:
        n = len(source)  # type: ignore[arg-type]
    except TypeError:
        return None
    return n if n > 0 else None


FFMPEG_LOGLEVEL_ENV = "OPENCV_FFMPEG_LOGLEVEL"  # read by OpenCV when its FFmpeg backend is first used


def quiet_opencv() -> None:
    """OpenCV logs warnings (e.g. FFmpeg timeouts) and FFmpeg its own messages (``[rtsp @ ...]
    method DESCRIBE failed: 404``, ``[tcp @ ...] Connection refused``) on stderr: keep only
    OpenCV's errors and none of FFmpeg's, so that a failure is the one line wristmark prints.
    A user who sets OPENCV_FFMPEG_LOGLEVEL (e.g. 32, FFmpeg's "info") sees FFmpeg's messages again.
    Takes effect for FFmpeg only before the process's first FFmpeg capture."""
    import os

    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    os.environ.setdefault(FFMPEG_LOGLEVEL_ENV, "-8")  # AV_LOG_QUIET


def _open(spec: str | Sequence[str | Path], o: SourceOptions) -> StereoSource:
    if not isinstance(spec, str):
        from wristmark.cvs.sources.images import open_image_pairs

        return open_image_pairs(spec)
    from wristmark.cvs.sources.stream import is_stream_url
    from wristmark.cvs.sources.v4l2 import is_device_spec

    if is_stream_url(spec):
        from wristmark.cvs.sources.stream import open_network_stream

        return open_network_stream(spec, o.layout, o.timeout, o.grayscale)
    if is_device_spec(spec):
        from wristmark.cvs.sources.v4l2 import open_v4l2_device

        return open_v4l2_device(spec, o.layout, o.size, o.fps, o.fourcc, o.timeout)
    path = Path(spec)
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        from wristmark.cvs.sources.images import open_image_folder

        return open_image_folder(path)
    if path.is_dir() or path.suffix.lower() in BAG_SUFFIXES:
        from wristmark.cvs.sources.bag import BagSource

        return BagSource(path, o.topics, paced=o.paced)
    from wristmark.cvs.sources.video import VideoFileSource

    if not path.exists() and "," in spec:
        return VideoFileSource(spec.split(","), o.layout, o.paced, o.timeout, o.grayscale)
    if not path.exists():
        raise FrameSourceError(f"{spec}: no such file, folder, camera or stream")
    return VideoFileSource([path], o.layout, o.paced, o.timeout, o.grayscale)


def open_stereo_source(spec: str | Sequence[str | Path], options: SourceOptions | None = None) -> StereoSource:
    """The source a SPEC names (module docstring), size-checked when ``options.image_size``
    is set; FrameSourceError (one line, naming the source) when it cannot be opened."""
    o = options or SourceOptions()
    o.validate()
    quiet_opencv()
    source = _open(spec, o)
    if o.image_size is None and not o.grayscale:
        return source
    size = None if o.image_size is None else (int(o.image_size[0]), int(o.image_size[1]))
    return CheckedSource(source, size, o.grayscale)
