"""Stereo frames from image files: a dataset folder (``pair_NN_left.*``, ``pair_NN_right.*``
in NN order) or an explicit list of LEFT RIGHT paths. ``t_capture`` is ``time.monotonic()``
when the pair was read; ``index`` counts pairs from 0. All paths are checked when the source
is made; an unreadable image is found when its pair is reached."""

from __future__ import annotations

import re
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame
from wristmark.models.errors import InputError

_PAIR_FILE = re.compile(r"^pair_(\d+)_(left|right)\.[^.]+$")


def read_image(path: Path) -> NDArray[np.uint8]:
    """Read an image as cv2.imread does (BGR or grayscale uint8); InputError if unreadable."""
    import cv2

    from wristmark.cvs.sources.image_decode import decode_image

    try:
        data = np.fromfile(str(path), dtype=np.uint8)
        img, said = decode_image(data) if data.size else (None, "empty file")
    except (OSError, cv2.error) as e:
        raise InputError(f"{path}: cannot read the image ({e})") from e
    if img is None:
        raise InputError(f"{path}: not a readable image (corrupt or unsupported format{': ' + said if said else ''})")
    if img.dtype != np.uint8:
        raise InputError(f"{path}: expected an 8-bit image, got {img.dtype}")
    return np.asarray(img)


def dataset_pairs(root: Path) -> list[tuple[Path, Path]]:
    """The (left, right) image paths of a dataset folder in NN order; FrameSourceError if it
    holds no pairs or a pair misses one side."""
    sides: dict[int, dict[str, Path]] = {}
    for p in root.iterdir():
        m = _PAIR_FILE.match(p.name)
        if m and p.is_file():
            sides.setdefault(int(m.group(1)), {})[m.group(2)] = p
    if not sides:
        raise FrameSourceError(f"{root}: no stereo pairs (pair_NN_left.*, pair_NN_right.*) in the folder")
    for n, s in sorted(sides.items()):
        if len(s) != 2:
            missing = "right" if "left" in s else "left"
            raise FrameSourceError(f"{root}: pair {n:02d} has no {missing} image")
    return [(s["left"], s["right"]) for _, s in sorted(sides.items())]


def pairs_from_paths(paths: Sequence[str | Path]) -> list[tuple[Path, Path]]:
    """LEFT RIGHT [LEFT RIGHT ...] as (left, right) pairs; InputError for an odd count or a
    missing file (every path is checked)."""
    ps = [Path(p) for p in paths]
    if len(ps) % 2:
        raise InputError(f"images come in LEFT RIGHT pairs, got {len(ps)} paths")
    for p in ps:
        if not p.is_file():
            raise InputError(f"{p}: image file not found")
    return list(zip(ps[0::2], ps[1::2]))


class ImagePairSource:
    """A finite stereo source over (left, right) image files, read in order."""

    def __init__(self, pairs: Sequence[tuple[Path, Path]], name: str) -> None:
        self.pairs = list(pairs)
        self.name = name
        self._next = 0

    def __len__(self) -> int:
        return len(self.pairs)

    @property
    def dropped(self) -> int:
        """Always 0: every pair is read."""
        return 0

    def read(self) -> StereoFrame | None:
        """The next pair, None after the last one; InputError for an unreadable image."""
        if self._next >= len(self.pairs):
            return None
        lp, rp = self.pairs[self._next]
        left, right = read_image(lp), read_image(rp)
        frame = StereoFrame(left, right, time.monotonic(), self._next, str(lp), str(rp))
        self._next += 1
        return frame

    def close(self) -> None:
        """Nothing to release."""
        self._next = len(self.pairs)


def open_image_folder(root: Path) -> ImagePairSource:
    """The pairs of a dataset folder as a source named after the folder."""
    return ImagePairSource(dataset_pairs(root), str(root))


def open_image_pairs(paths: Sequence[str | Path]) -> ImagePairSource:
    """An explicit LEFT RIGHT ... list as a source."""
    pairs = pairs_from_paths(paths)
    return ImagePairSource(pairs, f"{len(pairs)} image pairs")
