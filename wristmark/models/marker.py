"""The wrist marker (docs/design.md "The wrist marker", "The coded marker"): a checkered sleeve.

Frame {wm} at the sleeve centre, z along the arm's distal direction, x through corner 0.
Two rows of ``columns`` patches; column k spans [k beta, (k+1) beta) from x towards y. Upper row
(0 < z < row_height): patch k black for even k; lower row the opposite. X-corners at
[r cos(i beta), r sin(i beta), 0]; consecutive corners alternate in polarity.

A coded sleeve adds ``patches``: dark rectangles [a0, a1, z0, z1] (angle [rad] from x_wm
towards y_wm, values beyond 2 pi wrap; z [m]) drawn in addition to the checker rows. Its
``code`` (the decoder's key, docs/marker_code.md) says which of them are code cells: ``bands``
are the cells' z ranges [m] (symmetric under z -> -z, outside the checker rows) and ``words``
one string per column k of '1' (dark) / '0' (white), one character per band in the order of
``bands``; cell (k, b) spans column k's angles and band b's heights. The patches must draw the
code exactly (checked on load). The sleeve extends over [min z, max z] of all rows and patches.

A marker file may name its arm (``arm``: letters, digits, '_', '-', '.'; docs/design.md "Several
arms in one view"). ``check_marker_set`` refuses a set of marker files that could be confused:
two with the same arm name, or coded sleeves that share a code (cvs.marker.family checks margins).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from wristmark.models.config_io import from_mapping, load_layered
from wristmark.models.errors import ConfigError

Array = NDArray[np.float64]
Patch = tuple[float, float, float, float]
TWO_PI = 2.0 * math.pi
ARM_NAME = re.compile(r"[A-Za-z0-9_.-]{1,40}")


@dataclass(frozen=True)
class MarkerCode:
    """The code cells of a coded sleeve: ``bands`` [(z0, z1)] [m], ``words`` (one per column,
    one '0'/'1' per band; '1' = dark). See the module doc and docs/marker_code.md."""

    bands: tuple[tuple[float, float], ...] = ()
    words: tuple[str, ...] = ()

    def bits(self) -> NDArray[np.int8]:
        """The code as an array (columns, bands) of 1 (dark) / 0 (white)."""
        return np.array([[int(c) for c in w] for w in self.words], np.int8).reshape(len(self.words), len(self.bands))

    def mirror(self) -> NDArray[np.int_]:
        """For each band, the band it becomes under the half turn about x_wm (z -> -z)."""
        centres = np.array([0.5 * (a + b) for a, b in self.bands])
        return np.array([int(np.argmin(np.abs(centres + c))) for c in centres], int)


@dataclass(frozen=True)
class MarkerModel:
    """Marker geometry [m]: sleeve radius, patch columns, row height, tip offset along z_wm;
    optional dark ``patches`` [a0, a1, z0, z1] ([rad], [m]) and their ``code``; optional ``arm``
    name (module doc)."""

    radius: float = 0.00455
    columns: int = 12
    row_height: float = 0.0025
    tip_offset: float = 0.015
    patches: tuple[Patch, ...] = ()
    code: MarkerCode | None = None
    arm: str | None = None

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for k in ("radius", "row_height"):
            if getattr(self, k) <= 0:
                raise ConfigError(f"'{k}' must be > 0, got {getattr(self, k)}")
        if self.tip_offset < 0:
            raise ConfigError(f"'tip_offset' must be >= 0, got {self.tip_offset}")
        if self.columns < 4 or self.columns % 2:
            raise ConfigError(f"'columns' must be an even integer >= 4, got {self.columns}")
        for i, (a0, a1, z0, z1) in enumerate(self.patches):
            if not (a0 < a1 <= a0 + TWO_PI and z0 < z1):
                raise ConfigError(f"'patches[{i}]' must be [a0, a1, z0, z1] with a0 < a1 <= a0 + 2 pi, z0 < z1")
        if self.arm is not None and not ARM_NAME.fullmatch(self.arm):
            raise ConfigError(f"'arm' must be a name of letters, digits, '_', '-' or '.', got {self.arm!r}")
        if self.code is not None:
            self._validate_code(self.code)

    def _validate_code(self, code: MarkerCode) -> None:
        h = self.row_height
        if not code.bands or len(code.words) != self.columns:
            raise ConfigError(f"'code' needs bands and one word per column ({self.columns})")
        for i, (z0, z1) in enumerate(code.bands):
            if not z0 < z1 or (z1 > -h and z0 < h):
                raise ConfigError(f"'code.bands[{i}]' must be a z range outside the checker rows (|z| >= row_height)")
        mirror = code.mirror()
        for i, (z0, z1) in enumerate(code.bands):
            m0, m1 = code.bands[mirror[i]]
            if abs(m0 + z1) > 1e-9 or abs(m1 + z0) > 1e-9:
                raise ConfigError("'code.bands' must be symmetric under z -> -z (the half turn of the sleeve)")
        for k, w in enumerate(code.words):
            if len(w) != len(code.bands) or set(w) - {"0", "1"}:
                raise ConfigError(f"'code.words[{k}]' must be {len(code.bands)} characters of 0/1, got {w!r}")
        bits, beta = code.bits(), self.beta
        for k in range(self.columns):
            for b, (z0, z1) in enumerate(code.bands):
                for fa in (0.02, 0.5, 0.98):  # the cell is drawn by the patches, all of it
                    for fz in (0.02, 0.5, 0.98):
                        if self.is_black((k + fa) * beta, z0 + fz * (z1 - z0)) != bool(bits[k, b]):
                            raise ConfigError(f"'patches' do not draw code cell (column {k}, band {b}) "
                                              f"as 'code.words' says")

    @classmethod
    def load(cls, path: str | Path) -> MarkerModel:
        """Load and validate a marker.yaml."""
        return from_mapping(cls, load_layered(path), str(path))

    @property
    def beta(self) -> float:
        """Angular width of one patch column [rad]."""
        return TWO_PI / self.columns

    @property
    def z_extent(self) -> tuple[float, float]:
        """The sleeve's extent along z_wm [m]: min and max z of the rows and patches."""
        z0 = min([-self.row_height] + [p[2] for p in self.patches])
        z1 = max([self.row_height] + [p[3] for p in self.patches])
        return z0, z1

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

    def patch_array(self) -> Array:
        """The patches as an array (n, 4) [a0, a1, z0, z1] (rad, m); (0, 4) when there are none."""
        return np.array(self.patches, np.float64).reshape(-1, 4)

    def is_black(self, angle: float, z: float) -> bool:
        """Sleeve colour at angle [rad] and height z [m] in {wm} (True = dark): a checker patch
        (|z| < row_height) or a listed patch; white elsewhere on the sleeve."""
        a = angle % TWO_PI
        if abs(z) < self.row_height:
            k = int(math.floor(a / self.beta)) % self.columns
            if (k % 2 == 0) == (z > 0):
                return True
        return any(z0 <= z < z1 and (a - a0) % TWO_PI < a1 - a0 for a0, a1, z0, z1 in self.patches)

    def tip(self) -> Array:
        """Tip position in {wm} [m]."""
        return np.array([0.0, 0.0, self.tip_offset])


def check_marker_set(markers: Sequence[MarkerModel], names: Sequence[str]) -> None:
    """Refuse marker files that could be confused with each other (``names``: their file names
    for the message): with more than one, every one needs a ``code`` and an ``arm``, arm names
    and codes differ, and all share the cell layout (columns, radius, rows, bands). ConfigError,
    one line naming the files and the cause."""
    if len(markers) < 2:
        return
    for m, n in zip(markers, names):
        if m.code is None or m.arm is None:
            raise ConfigError(f"{n}: several markers need coded sleeves that name their arm ('code' and 'arm')")
    first = markers[0]
    for i, (m, n) in enumerate(zip(markers, names)):
        if (m.columns, m.radius, m.row_height) != (first.columns, first.radius, first.row_height) or \
                m.code is None or first.code is None or m.code.bands != first.code.bands:
            raise ConfigError(f"{n} and {names[0]}: the sleeves of one set need the same geometry and code bands")
        for m2, n2 in zip(markers[:i], names[:i]):
            if m.arm == m2.arm:
                raise ConfigError(f"{n} and {n2}: the same arm name '{m.arm}'")
            if m2.code is not None and m.code.words == m2.code.words:
                raise ConfigError(f"{n} and {n2}: the same code (arm '{m2.arm}' and arm '{m.arm}')")
