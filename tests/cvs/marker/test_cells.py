"""cvs.marker.cells: the references of a code cell's darkness."""

from __future__ import annotations

import numpy as np

from wristmark.cvs.marker.cells import cell_darkness

NAN = float("nan")
# one cell; references 0-3: its own (dark) patch, two neighbours (white) and the other row's own column (white)
DARK, WHITE = np.array([[0, 0, 0]]), np.array([[1, 2, 3]])


def _darkness(cell: float, own: float, left: float, right: float, other_row: float) -> float:
    d, phase = cell_darkness(np.array([[cell, own, left, right, other_row]]), 1, DARK, WHITE, 25.0)
    assert phase == (0 if np.isfinite(d[0]) else -1)  # the references' phase (-1: none with contrast)
    return float(d[0])


def test_both_neighbours_seen_give_their_mean() -> None:
    assert np.isclose(_darkness(110.0, 20.0, 200.0, 100.0, 50.0), (150.0 - 110.0) / (150.0 - 20.0))


def test_one_neighbour_alone_is_replaced_by_the_other_rows_patch_of_the_same_column() -> None:
    """Near the limb the one neighbour seen faces the light better than the cell: a white cell at
    the other row's shading reads white, not half dark (0.56 against the lone neighbour)."""
    assert np.isclose(_darkness(100.0, 20.0, 200.0, NAN, 100.0), 0.0)
    assert np.isclose(_darkness(100.0, 20.0, NAN, 200.0, 100.0), 0.0)


def test_no_reference_no_reading() -> None:
    assert np.isnan(_darkness(100.0, 20.0, 200.0, NAN, NAN))
