"""Image bytes decoded by OpenCV without its codecs writing to our stderr.

libpng (and libjpeg) print their own warnings straight to file descriptor 2 ("libpng error: PNG
input buffer is incomplete"); OpenCV's log level does not reach them. :func:`decode_image`
captures that descriptor around ``cv2.imdecode`` and returns what the codec said, so that a
command can put it into its own one-line error instead.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterator

import cv2
import numpy as np
from numpy.typing import NDArray

_STDERR_FD = 2
_LOCK = threading.Lock()  # one capture at a time: the descriptor is process-wide


@contextlib.contextmanager
def _captured_stderr(said: list[str]) -> Iterator[None]:
    """Send file descriptor 2 to a temporary file inside the block; append its text to ``said``."""
    try:
        sys.stderr.flush()
        saved = os.dup(_STDERR_FD)
    except (OSError, ValueError, AttributeError):  # no stderr to redirect: decode as is
        yield
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), _STDERR_FD)
        try:
            yield
        finally:
            os.dup2(saved, _STDERR_FD)
            os.close(saved)
            tmp.seek(0)
            said.append(tmp.read().decode(errors="replace"))


def decode_image(data: NDArray[np.uint8], flags: int = cv2.IMREAD_UNCHANGED) -> tuple[NDArray[np.uint8] | None, str]:
    """``cv2.imdecode(data, flags)`` and the codec's first message line ("" when it said nothing);
    the image is None when the bytes do not decode."""
    said: list[str] = []
    with _LOCK, _captured_stderr(said):
        img = cv2.imdecode(data, flags)
    lines = [ln.strip() for ln in "".join(said).splitlines() if ln.strip()]
    return (None if img is None else np.asarray(img)), (lines[0] if lines else "")
