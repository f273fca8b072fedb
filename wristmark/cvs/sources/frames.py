"""Stereo frames and the protocol every frame source implements (docs/design.md "Stereo frame sources").

A :class:`StereoFrame` is what a stereo endoscope hands out: the left and right 8-bit images,
the capture time on the host's ``time.monotonic()`` clock [s] and the frame's index. A
:class:`StereoSource` hands out frames one by one: ``read()`` returns the next frame (a live
source: the newest one, stale frames dropped and counted in ``dropped``), ``None`` at the end of
a finite source (a file, a bag, a folder), and raises :class:`FrameSourceError` (one line, naming
the source) when a stream stalls, a device cannot be opened, or a frame has the wrong size.

The implementations live in ``cvs/frame_source_*.py``; ``cvs.sources.open_source.open_stereo_source``
turns a ``--source``/``--camera`` SPEC into one of them.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError


class FrameSourceError(InputError):
    """A frame source cannot deliver: cannot be opened, stalled, ended early, or a bad frame."""


@dataclass(frozen=True)
class StereoFrame:
    """One stereo frame: left and right 8-bit images (HxW grey or HxWx3 BGR), capture time
    ``t_capture`` on the host's ``time.monotonic()`` clock [s], and ``index`` (0, 1, ... in the
    source's order; a live source's index counts delivered and dropped frames alike).
    ``name_left``/``name_right`` say where the images came from (a path, or the source's name)."""

    left: NDArray[np.uint8]
    right: NDArray[np.uint8]
    t_capture: float
    index: int
    name_left: str = ""
    name_right: str = ""


@runtime_checkable
class StereoSource(Protocol):
    """Anything that hands out stereo frames (:class:`StereoFrame`: pixels, capture time [s]; see the
    module docstring for the contract)."""

    name: str

    def read(self) -> StereoFrame | None:
        """The next frame (live: the newest); None at the end of a finite source."""
        ...

    @property
    def dropped(self) -> int:
        """Frames that were captured but never handed out (stale, or skipped by pacing)."""
        ...

    def close(self) -> None:
        """Release the device, file or connection (idempotent)."""
        ...


def frames(source: StereoSource, limit: int | None = None) -> Iterator[StereoFrame]:
    """Iterate over ``source`` until it ends or ``limit`` frames were handed out."""
    n = 0
    while limit is None or n < limit:
        frame = source.read()
        if frame is None:
            return
        n += 1
        yield frame


def check_frame_size(frame: StereoFrame, image_size: tuple[int, int], source: str) -> None:
    """Raise FrameSourceError unless both halves are ``image_size`` = (width, height) [px]."""
    w, h = int(image_size[0]), int(image_size[1])
    for side, img in (("left", frame.left), ("right", frame.right)):
        got = (int(img.shape[1]), int(img.shape[0]))
        if got != (w, h):
            raise FrameSourceError(
                f"{source}: {side} image is {got[0]}x{got[1]} px but the calibration's image_size is {w}x{h}"
            )
