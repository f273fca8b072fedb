"""The coded sleeve's code (docs/marker_code.md): cell layout, hypotheses and Hamming margins.

The corners fix the sleeve's pose up to its symmetries: a roll by a whole number s of columns
(corner indices are relative) and the half turn about x_wm (the direction of z_wm). A pose
hypothesis is ``(s, +1)``: relative column j is absolute column j + s; or ``(s, -1)``: the
sleeve is half turned and relative column j is absolute column s - j - 1 (its bands mirrored).
For the code cells a hypothesis predicts the colour of every cell, so the cells seen decide
between the 2 n hypotheses (cvs.marker.decode).

``CODE_WORDS`` (12 columns x 4 bands, found by the search of ``search_code``): every window of
3 consecutive columns differs from every other window of 3, read in either direction and at
any cyclic shift, in at least 4 of its 12 cells (``window_margin(bits, mirror, 3) == 4``); two
columns still identify the column uniquely (margin 2).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.marker import MarkerCode, MarkerModel

IntArray = NDArray[np.int_]
# 12 columns; per column the bands from the lowest z to the highest ('1' = dark)
CODE_WORDS = ("1001", "0111", "1000", "0100", "0101", "0011", "1011", "1111", "0110", "0100", "1100", "0000")
GAP = 0.0004  # white between a checker row and the first code band [m]
BAND = 0.0010  # height of a code band [m]
BAND_GAP = 0.0003  # white between the two code bands of a side [m]


def hypotheses(bits: NDArray[np.int8], mirror: IntArray) -> tuple[NDArray[np.int8], IntArray, IntArray]:
    """Every hypothesis' predicted cells: ``pred`` (2 n, n, bands) for relative columns j and
    bands b, with ``shift`` (2 n,) and ``direction`` (2 n,) (+1 / -1; module doc)."""
    n = bits.shape[0]
    j = np.arange(n)
    pred, shift, direction = [], [], []
    for s in range(n):
        pred.append(bits[(j + s) % n])
        pred.append(bits[(s - j - 1) % n][:, mirror])
        shift += [s, s]
        direction += [1, -1]
    return np.array(pred, np.int8), np.array(shift, int), np.array(direction, int)


def window_margin(bits: NDArray[np.int8], mirror: IntArray, width: int, shift_step: int = 1) -> int:
    """Least number of cells in which two hypotheses differ over any window of ``width``
    consecutive columns (shifts that are multiples of ``shift_step``, both directions)."""
    pred, shift, _ = hypotheses(bits, mirror)
    keep = shift % shift_step == 0
    pred = pred[keep]
    n = bits.shape[0]
    worst = 10**9
    for j0 in range(n):
        cols = (j0 + np.arange(width)) % n
        w = pred[:, cols].reshape(pred.shape[0], -1)
        d = (w[:, None, :] != w[None, :, :]).sum(axis=2)
        np.fill_diagonal(d, 10**9)
        worst = min(worst, int(d.min()))
    return worst


def search_code(seed: int, columns: int = 12, bands: int = 4, restarts: int = 30, steps: int = 1500
                ) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """The search that found ``CODE_WORDS``: hill climbing on single-cell flips of random codes,
    maximising (margin of 3 columns, margin of 2 columns) over all shifts and both directions;
    returns the best score and words (docs/marker_code.md)."""
    rng = np.random.default_rng(seed)
    mirror = np.arange(bands)[::-1].copy()

    def score(b: NDArray[np.int8]) -> tuple[int, ...]:
        return window_margin(b, mirror, 3), window_margin(b, mirror, 2)

    best: tuple[tuple[int, ...], NDArray[np.int8]] | None = None
    for _ in range(restarts):
        b = rng.integers(0, 2, (columns, bands)).astype(np.int8)
        s = score(b)
        for _ in range(steps):
            c = b.copy()
            c[rng.integers(columns), rng.integers(bands)] ^= 1
            sc = score(c)
            if sc >= s:
                b, s = c, sc
        if best is None or s > best[0]:
            best = (s, b)
    assert best is not None
    return best[0], tuple("".join(str(int(v)) for v in row) for row in best[1])


def coded_marker(base: MarkerModel | None = None, words: tuple[str, ...] = CODE_WORDS) -> MarkerModel:
    """The coded sleeve of configs/marker_coded.yaml: ``base``'s checker rows and, on each side,
    len(word) / 2 bands of code cells (GAP, then BAND, BAND_GAP, BAND, ...) drawn as one patch
    per dark cell (two bands per side for ``CODE_WORDS``; sleeve families may use more)."""
    from dataclasses import replace

    m = base or MarkerModel()
    h = m.row_height
    per_side = len(words[0]) // 2
    up = [(h + GAP + i * (BAND + BAND_GAP), h + GAP + i * (BAND + BAND_GAP) + BAND) for i in range(per_side)]
    bands = tuple(sorted([(-z1, -z0) for z0, z1 in up] + up))
    code = MarkerCode(bands=tuple((float(a), float(b)) for a, b in bands), words=tuple(words))
    beta = 2 * math.pi / m.columns
    patches = tuple((k * beta, (k + 1) * beta, z0, z1) for k, w in enumerate(words)
                    for (z0, z1), c in zip(bands, w) if c == "1")
    out = replace(m, patches=tuple(tuple(float(v) for v in p) for p in patches), code=code)  # type: ignore[misc]
    out.validate()
    return out
