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


def _patches(upper: list[float], lower: list[float]) -> np.ndarray:
    return np.array([upper + lower], float)  # one camera: the upper row's patches, then the lower row's


def test_the_columns_own_patches_give_the_phase_whatever_the_shading_across_them() -> None:
    """Columns 0-4 of a glossy sleeve under a coaxial light (path-traced 1414/47's left view): the
    column facing the camera is lifted by its highlight, its black patch (143) above its
    neighbours' whites (85-92), but each column's two patches keep their order."""
    from wristmark.cvs.marker.cells import column_phase

    upper, lower = [46.0, 5.0, 189.0, 5.0, 46.0], [4.0, 92.0, 143.0, 85.0, 5.0]
    assert column_phase(_patches(upper, lower), 25.0) == 1  # even columns' upper patch the lighter
    assert column_phase(_patches(lower, upper), 25.0) == 0
    assert column_phase(np.vstack([_patches(upper, lower)] * 2), 25.0) == 1  # both cameras agree


def test_a_column_against_the_others_or_too_few_columns_give_no_phase() -> None:
    from wristmark.cvs.marker.cells import column_phase

    upper, lower = [46.0, 5.0, 189.0, 5.0, 46.0], [4.0, 92.0, 143.0, 85.0, 5.0]
    assert column_phase(_patches(upper[:3] + [85.0, 46.0], lower[:3] + [5.0, 5.0]), 25.0) == -1  # column 3 turned
    assert column_phase(_patches(upper[:2] + [NAN] * 3, lower[:2] + [NAN] * 3), 25.0) == -1  # 2 columns seen
    assert column_phase(_patches([40.0, 30.0, 40.0], [30.0, 40.0, 30.0]), 25.0) == -1  # no contrast (10 < 25)
