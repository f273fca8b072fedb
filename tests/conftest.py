"""Shared pytest fixtures: frames that carry their own id (readable after JPEG/MJPG coding)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray

ID_BITS = 12
ID_BLOCK = 16  # px per bit block: large enough to survive JPEG at quality ~80


def stamp_id(image: NDArray[np.uint8], k: int) -> NDArray[np.uint8]:
    """A copy of ``image`` with ``k`` written as ID_BITS black/white blocks along the top row."""
    out = image.copy()
    for b in range(ID_BITS):
        out[:ID_BLOCK, b * ID_BLOCK : (b + 1) * ID_BLOCK] = 255 if (k >> b) & 1 else 0
    return out


def read_id(image: NDArray[np.uint8]) -> int:
    """The id :func:`stamp_id` wrote (block centres thresholded at mid-grey)."""
    k, q = 0, ID_BLOCK // 4
    for b in range(ID_BITS):
        block = image[q : ID_BLOCK - q, b * ID_BLOCK + q : (b + 1) * ID_BLOCK - q]
        if float(np.mean(block)) > 127:
            k |= 1 << b
    return k


def id_view(k: int, side: int, width: int = 320, height: int = 180) -> NDArray[np.uint8]:
    """A BGR view (side 0 left, 1 right) whose id reads back as ``2 * k + side``."""
    img = np.full((height, width, 3), 90 + 60 * side, np.uint8)
    img[height // 2 :, :, 1] = 40 * side + 20  # some structure below the id row
    return stamp_id(img, 2 * k + side)


@pytest.fixture
def frame_ids() -> tuple[Callable[..., NDArray[np.uint8]], Callable[[NDArray[np.uint8]], int]]:
    """(id_view, read_id): make a view carrying an id, read an id back."""
    return id_view, read_id
