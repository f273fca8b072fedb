"""Sleeve families (docs/marker_code.md "Families"): coded sleeves whose code windows never collide.

A family is a list of codes (columns x bands, the same cell layout) such that the 2 n
hypotheses (cvs.marker.code) of **all** members together keep the single-error-correcting
margin: over any ``width`` consecutive columns, the cells predicted by any two hypotheses of
the union (of one member or of two) differ in at least ``margin`` cells. Then a sleeve's cells
can never be read as another member's (decoder: cvs.marker.decode with a marker set).

Because a hypothesis set contains every cyclic shift and both directions, the set of windows
at any start column is the same as at column 0: ``family_margin`` enumerates each member's 2 n
windows of the width once. ``search_family`` is the simulated annealing that found the
shipped ``FAMILIES`` (kept for reproducibility; the shipped families are data, so ``wristmark
marker family`` is instant and deterministic).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError
from wristmark.models.marker import ARM_NAME, MarkerModel

Bits = NDArray[np.int8]

# Shipped families: bands per side -> members (each 12 words, one character per band, lowest z
# first). Found by ``search_family`` (seeds and settings in docs/marker_code.md "Families").
FAMILIES: dict[int, tuple[tuple[str, ...], ...]] = {
    # 2 bands per side (the 10.4 mm sleeve of configs/marker_coded.yaml): 2 arms, found by the
    # lead's annealing (seed 3); search_family(2, 4, seed=4, restarts=1, fixed=[arm0]) completes arm0
    2: (
        ("0110", "0000", "0000", "1001", "0011", "1001", "1010", "1010", "1100", "1010", "0101", "1100"),
        ("0000", "1111", "0110", "0101", "0110", "1100", "1111", "1010", "1001", "1111", "0000", "1100"),
    ),
    # 3 bands per side (13.0 mm sleeve): 8 arms; search_family(8, 6, seed=1, restarts=1, margin2=2)
    3: (
        ("001000", "111111", "001011", "100101", "101110", "011001", "100011", "001111", "111001", "101011",
         "000100", "010100"),
        ("011110", "000101", "001100", "010001", "000011", "011011", "000011", "011110", "010110", "111100",
         "010101", "011111"),
        ("111010", "100101", "011100", "011111", "110011", "101111", "010011", "101000", "101011", "110110",
         "101000", "000100"),
        ("011111", "001111", "001001", "100001", "010101", "100000", "001010", "101011", "001110", "111100",
         "000010", "010110"),
        ("010110", "111011", "111000", "111010", "111011", "011010", "100010", "101110", "110101", "011110",
         "011000", "001001"),
        ("000000", "010011", "110001", "011101", "111011", "000010", "000011", "000100", "100111", "010010",
         "001101", "001011"),
        ("101101", "000010", "010001", "111011", "010000", "011011", "001101", "110011", "001011", "110010",
         "100011", "100011"),
        ("101011", "000001", "110001", "111111", "001000", "110110", "010011", "000010", "111100", "111101",
         "101101", "011011"),
    ),
}
FAMILY_MARGIN = 4  # least cell difference over 3 columns across a shipped family
FAMILY_WIDTH = 3


def words_to_bits(words: Sequence[str]) -> Bits:
    """Code words -> array (columns, bands) of 0/1."""
    return np.array([[int(c) for c in w] for w in words], np.int8)


def bits_to_words(bits: Bits) -> tuple[str, ...]:
    """Array (columns, bands) of 0/1 -> code words."""
    return tuple("".join(str(int(v)) for v in row) for row in bits)


def _windows(bits: Bits, width: int) -> NDArray[np.bool_]:
    """The 2 n windows (hypotheses (s, +), (s, -)) of ``width`` columns at start 0, flattened."""
    n, nb = bits.shape
    mirror = np.arange(nb)[::-1]
    j = np.arange(width)
    out = []
    for s in range(n):
        out.append(bits[(j + s) % n].reshape(-1))
        out.append(bits[(s - j - 1) % n][:, mirror].reshape(-1))
    return np.array(out, bool)


def family_distances(codes: Sequence[Bits], width: int) -> NDArray[np.int_]:
    """Cell differences between all hypotheses of all members over ``width`` columns, shape
    (2 n M, 2 n M), the diagonal set to a large number."""
    w = np.concatenate([_windows(np.asarray(b, np.int8), width) for b in codes]).astype(np.int32)
    d = w @ (1 - w).T + (1 - w) @ w.T
    np.fill_diagonal(d, 10**6)
    return np.asarray(d)


def family_margin(codes: Sequence[Bits], width: int) -> int:
    """Least cell difference between two hypotheses of the family (same or different member)
    over any ``width`` consecutive columns, both directions, every shift (module doc)."""
    return int(family_distances(codes, width).min())


def search_family(members: int, bands: int, seed: int, columns: int = 12, steps: int = 20000,
                  restarts: int = 20, margin: int = FAMILY_MARGIN, margin2: int = 0,
                  fixed: Sequence[Bits] = (), temperature: tuple[float, float] = (2.0, 0.02)
                  ) -> tuple[Bits, ...] | None:
    """Simulated annealing on single-cell flips: ``members`` codes of ``columns`` x ``bands``
    (``fixed`` codes first, never flipped) whose union keeps ``margin`` over 3 columns (and
    ``margin2`` over 2), the temperature falling geometrically from ``temperature[0]`` to
    ``[1]`` over ``steps``; returns the first family found, or None after ``restarts``."""
    rng = np.random.default_rng(seed)

    def cost(codes: list[Bits]) -> float:
        c = float(np.maximum(0, margin - family_distances(codes, 3)).sum())
        if margin2:
            c += 0.5 * float(np.maximum(0, margin2 - family_distances(codes, 2)).sum())
        return c

    nfix = len(fixed)
    t0, t1 = temperature
    for _ in range(restarts):
        codes = [np.asarray(f, np.int8).copy() for f in fixed]
        codes += [rng.integers(0, 2, (columns, bands)).astype(np.int8) for _ in range(members - nfix)]
        c = cost(codes)
        for k in range(steps):
            if c == 0:
                return tuple(codes)
            temp = t0 * (t1 / t0) ** (k / steps)
            m = int(rng.integers(nfix, members))
            i, b = int(rng.integers(columns)), int(rng.integers(bands))
            codes[m][i, b] ^= 1
            c2 = cost(codes)
            if c2 <= c or rng.uniform() < math.exp(-(c2 - c) / temp):
                c = c2
            else:
                codes[m][i, b] ^= 1
        if c == 0:
            return tuple(codes)
    return None


def largest_family(bands_per_side: int | None = None) -> int:
    """Members of the largest shipped family (of the given bands per side, else of any)."""
    sizes = [len(f) for b, f in FAMILIES.items() if bands_per_side in (None, b)]
    return max(sizes, default=0)


def family_markers(arms: int, base: MarkerModel | None = None, names: Sequence[str] | None = None,
                   bands_per_side: int | None = None) -> list[MarkerModel]:
    """``arms`` coded sleeves of the shipped family with ``bands_per_side`` (default: the fewest,
    i.e. the shortest sleeve, that has that many members), named ``arm0``, ``arm1``, ... (or
    ``names``). A request larger than the family raises InputError naming the cause."""
    from wristmark.cvs.marker.code import coded_marker

    if arms < 1:
        raise InputError(f"--arms must be >= 1, got {arms}")
    if bands_per_side is not None and bands_per_side not in FAMILIES:
        raise InputError(f"--bands-per-side must be one of {sorted(FAMILIES)}, got {bands_per_side}")
    fits = [b for b in sorted(FAMILIES) if bands_per_side in (None, b) and len(FAMILIES[b]) >= arms]
    if not fits:
        which = "" if bands_per_side is None else f" with {bands_per_side} bands per side"
        raise InputError(f"--arms {arms}: the largest sleeve family{which} that keeps the single-error margin "
                         f"({FAMILY_MARGIN} cells over {FAMILY_WIDTH} columns) has "
                         f"{largest_family(bands_per_side)} arms")
    words = FAMILIES[fits[0]]
    names = list(names) if names is not None else [f"arm{i}" for i in range(arms)]
    if len(names) != arms or len(set(names)) != arms:
        raise InputError(f"--names: need {arms} distinct arm names, got {','.join(names)}")
    for name in names:
        if not ARM_NAME.fullmatch(name):
            raise InputError(f"--names: '{name}' is not a name of letters, digits, '_', '-' or '.'")
    out = []
    for name, w in zip(names, words[:arms]):
        m = replace(coded_marker(base, w), arm=name)
        m.validate()
        out.append(m)
    return out


def marker_file_text(marker: MarkerModel, note: str = "") -> str:
    """A coded marker as the text of a marker file (the keys of configs/marker_coded.yaml plus
    ``arm``), loadable by ``MarkerModel.load``; ``note``: a first comment line."""
    code = marker.code
    if code is None or marker.arm is None:
        raise InputError("a family marker file needs a code and an arm name")

    def num(v: float) -> str:
        return f"{v:.10g}"

    lines = [f"# {note}" if note else "# Coded wrist marker of a sleeve family (docs/marker_code.md \"Families\").",
             "# Print it with `wristmark marker print --marker THIS.yaml --out sleeve.pdf`. SI units.",
             f"arm: {marker.arm}            # the arm this sleeve is wrapped on (track reports it as \"arm\")",
             f"radius: {num(marker.radius)}      # sleeve radius [m]",
             f"columns: {marker.columns}          # patches per row; beta = 2 pi / columns",
             f"row_height: {num(marker.row_height)}   # height of each checker row [m]",
             f"tip_offset: {num(marker.tip_offset)}    # marker centre -> tip along z_wm [m]",
             "# dark rectangles [a0, a1, z0, z1]: angle from x_wm towards y_wm [rad], z along z_wm [m]",
             "patches:"]
    lines += [f"  - [{', '.join(num(v) for v in p)}]" for p in marker.patches]
    lines += ["# the decoder's key: which patches are code cells (cvs.marker: MarkerCode)", "code:",
              "  # z ranges [m] of the cell bands, lowest first (symmetric under z -> -z)", "  bands:"]
    lines += [f"    - [{num(a)}, {num(b)}]" for a, b in code.bands]
    lines += ["  # per column k: one character per band (order of bands), 1 = dark cell",
              "  words: [" + ", ".join(f'"{w}"' for w in code.words) + "]"]
    return "\n".join(lines) + "\n"
