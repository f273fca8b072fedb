"""The path-traced 1080p stereo pairs committed for the tracker's tests (tests/data/pbr)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np

__all__ = ["PBR_DATA", "load_pbr_pair"]

PBR_DATA = Path(__file__).resolve().parents[2] / "data" / "pbr"


def load_pbr_pair(name: str) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The grey left and right views (uint8, 1080 x 1920) of ``tests/data/pbr/NAME/pair_00_*``
    and its truth (``T_left_marker`` and ``tip_left`` in the left camera frame [m])."""
    folder = PBR_DATA / name
    truth = json.loads((folder / "truth.json").read_text())
    left, right = (cv2.imread(str(folder / f"pair_00_{v}.png"), cv2.IMREAD_GRAYSCALE) for v in ("left", "right"))
    if left is None or right is None:
        raise FileNotFoundError(f"no pair_00_left.png / pair_00_right.png in {folder}")
    return left, right, truth
