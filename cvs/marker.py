"""The wrist marker (DESIGN.md "The wrist marker"): a checkered sleeve around the arm.

Frame {wm} at the sleeve centre, z along the arm's distal direction, x through corner 0.
Two rows of ``columns`` patches; column k spans [k beta, (k+1) beta) from x towards y. Upper row
(0 < z < row_height): patch k black for even k; lower row the opposite. X-corners at
[r cos(i beta), r sin(i beta), 0]; consecutive corners alternate in polarity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from models.config_io import from_mapping, load_yaml
from models.errors import ConfigError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MarkerModel:
    """Marker geometry [m]: sleeve radius, patch columns, row height, tip offset along z_wm."""

    radius: float = 0.00455
    columns: int = 12
    row_height: float = 0.0025
    tip_offset: float = 0.015

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for k in ("radius", "row_height"):
            if getattr(self, k) <= 0:
                raise ConfigError(f"'{k}' must be > 0, got {getattr(self, k)}")
        if self.tip_offset < 0:
            raise ConfigError(f"'tip_offset' must be >= 0, got {self.tip_offset}")
        if self.columns < 4 or self.columns % 2:
            raise ConfigError(f"'columns' must be an even integer >= 4, got {self.columns}")

    @classmethod
    def load(cls, path: str | Path) -> MarkerModel:
        """Load and validate a marker.yaml."""
        return from_mapping(cls, load_yaml(path), str(path))

    @property
    def beta(self) -> float:
        """Angular width of one patch column [rad]."""
        return 2.0 * math.pi / self.columns

    def corners(self) -> Array:
        """X-corner positions in {wm}, shape (columns, 3) [m] (paper eq. 11)."""
        a = self.beta * np.arange(self.columns)
        return np.column_stack([self.radius * np.cos(a), self.radius * np.sin(a), np.zeros_like(a)])

    def corner_normals(self) -> Array:
        """Outward surface normals at the corners in {wm}, shape (columns, 3)."""
        a = self.beta * np.arange(self.columns)
        return np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])

    def polarity(self, i: int) -> int:
        """+1 if the patch just above corner i in z and after it in angle (upper row, column i)
        is black, else -1. Alternates with i."""
        return 1 if i % 2 == 0 else -1

    def is_black(self, angle: float, z: float) -> bool:
        """Patch colour at sleeve angle [rad] and height z [m] in {wm} (True = black)."""
        k = int(math.floor((angle % (2 * math.pi)) / self.beta)) % self.columns
        upper = z > 0
        return (k % 2 == 0) == upper

    def tip(self) -> Array:
        """Tip position in {wm} [m]."""
        return np.array([0.0, 0.0, self.tip_offset])
