"""How one camera frame holds a stereo pair: side by side (``sbs``, left camera in the left
half) or top-bottom (``tb``, left camera on top); :func:`split_stereo` cuts it in two views."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError

LAYOUTS = ("sbs", "tb")


def check_layout(layout: str) -> str:
    """``layout`` if it is one of LAYOUTS, else FrameSourceError listing them."""
    if layout not in LAYOUTS:
        raise FrameSourceError(f"unknown stereo layout '{layout}' (valid: {', '.join(LAYOUTS)})")
    return layout


def split_stereo(image: NDArray[np.uint8], layout: str, source: str) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """(left, right) views of one frame (no copy); FrameSourceError if the frame cannot be cut
    in two equal halves along ``layout``'s axis."""
    check_layout(layout)
    h, w = image.shape[:2]
    if layout == "sbs":
        if w % 2:
            raise FrameSourceError(f"{source}: a side-by-side frame needs an even width, got {w}x{h} px")
        return image[:, : w // 2], image[:, w // 2 :]
    if h % 2:
        raise FrameSourceError(f"{source}: a top-bottom frame needs an even height, got {w}x{h} px")
    return image[: h // 2], image[h // 2 :]


def join_stereo(left: NDArray[np.uint8], right: NDArray[np.uint8], layout: str = "sbs") -> NDArray[np.uint8]:
    """One frame holding ``left`` and ``right`` (same shape) in ``layout`` (the inverse of
    :func:`split_stereo`)."""
    check_layout(layout)
    if left.shape != right.shape:
        raise FrameSourceError(f"left and right images differ in shape: {left.shape} vs {right.shape}")
    return np.ascontiguousarray(np.concatenate([left, right], axis=1 if layout == "sbs" else 0))
