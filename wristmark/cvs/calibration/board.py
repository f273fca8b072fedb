"""Calibration boards and their detection in one image (``wristmark calibrate --board``).

``chessboard:CxR:SQUARE`` — C x R inner corners, SQUARE [m]: found by our X-corner stage
(cvs.corners.detector.detect_xcorners with BOARD_SETTINGS) and ordered by
cvs.corners.planar_board.assemble_grid like cv2.findChessboardCornersSB.
``charuco:CxR:SQUARE:MARKER:DICT`` — C x R squares (OpenCV's convention), square and marker
sides [m], DICT an OpenCV dictionary name (DICT_5X5_100, ...): cv2.aruco.CharucoDetector.
Object points lie in the board's plane z = 0 [m]; image points are raw (distorted) pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.corners.detector import BOARD_SETTINGS, assemble_grid, detect_xcorners
from wristmark.cvs.gray_image import check_image, to_gray
from wristmark.models.errors import InputError

Array = NDArray[np.float64]
_FORMS = "chessboard:CxR:SQUARE or charuco:CxR:SQUARE:MARKER:DICT (lengths in metres, e.g. chessboard:9x6:0.025)"


@dataclass(frozen=True)
class BoardView:
    """The board found in one image: ids (which board corners), their object points (N, 3) [m]
    and raw image points (N, 2) [px]."""

    ids: NDArray[np.int64]
    object_points: Array
    image_points: Array


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board: kind 'chessboard' (columns x rows inner corners) or 'charuco'
    (columns x rows squares), square and marker side [m], ArUco dictionary name."""

    kind: str
    columns: int
    rows: int
    square: float
    marker: float = 0.0
    dictionary: str = ""

    @classmethod
    def parse(cls, text: str) -> BoardSpec:
        """Parse ``--board`` (see the module docstring); InputError naming the expected form."""
        parts = text.split(":")
        kind = parts[0].lower()
        if kind not in ("chessboard", "charuco") or len(parts) != (3 if kind == "chessboard" else 5):
            raise InputError(f"--board '{text}': expected {_FORMS}")
        try:
            c, r = (int(v) for v in parts[1].lower().split("x"))
            square = float(parts[2])
            marker = float(parts[3]) if kind == "charuco" else 0.0
        except ValueError:
            raise InputError(f"--board '{text}': expected {_FORMS}") from None
        if c < 2 or r < 2 or not (0 < square < 1.0) or (kind == "charuco" and not 0 < marker < square):
            raise InputError(f"--board '{text}': need C, R >= 2, 0 < SQUARE < 1 m (metres, not mm)"
                             + (" and 0 < MARKER < SQUARE" if kind == "charuco" else ""))
        spec = cls(kind, c, r, square, marker, parts[4] if kind == "charuco" else "")
        if kind == "charuco":
            spec.charuco_board()  # checks the dictionary name
        return spec

    @property
    def corner_count(self) -> int:
        """Corners of a complete view."""
        return self.columns * self.rows if self.kind == "chessboard" else (self.columns - 1) * (self.rows - 1)

    def all_object_points(self) -> Array:
        """Every board corner in the board frame (corner_count, 3) [m], in id order."""
        if self.kind == "charuco":
            return np.asarray(self.charuco_board().getChessboardCorners(), float).reshape(-1, 3)
        g = np.mgrid[0 : self.columns, 0 : self.rows].T.reshape(-1, 2)
        return np.c_[g * self.square, np.zeros(len(g))]

    def charuco_board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV ChArUco board of this spec."""
        name = self.dictionary.upper()
        if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
            valid = ", ".join(n for n in dir(cv2.aruco) if n.startswith("DICT_") and "_1000" not in n)
            raise InputError(f"--board: unknown ArUco dictionary '{self.dictionary}' (valid: {valid}, ...)")
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
        return cv2.aruco.CharucoBoard((self.columns, self.rows), self.square, self.marker, d)


class BoardDetector:
    """Finds a :class:`BoardSpec` board in images (grey or BGR uint8)."""

    def __init__(self, spec: BoardSpec, min_corners: int = 6) -> None:
        self.spec = spec
        self.min_corners = int(min_corners)
        self._objp = spec.all_object_points()
        self._charuco = cv2.aruco.CharucoDetector(spec.charuco_board()) if spec.kind == "charuco" else None

    def detect(self, image: NDArray[np.uint8]) -> BoardView | None:
        """The board's corners in ``image``, or None when it is not found (chessboard: the whole
        grid; ChArUco: at least ``min_corners`` interpolated corners)."""
        gray = to_gray(check_image(image))
        if self._charuco is None:
            grid = assemble_grid(detect_xcorners(gray, BOARD_SETTINGS), (self.spec.columns, self.spec.rows), gray)
            if grid is None:
                return None
            return BoardView(np.arange(self.spec.corner_count), self._objp, np.asarray(grid, float).reshape(-1, 2))
        corners, found, _mc, _mi = self._charuco.detectBoard(gray)
        if found is None or len(found) < self.min_corners:
            return None
        idx = np.asarray(found, np.int64).ravel()
        return BoardView(idx, self._objp[idx], np.asarray(corners, float).reshape(-1, 2))
