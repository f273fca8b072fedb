"""Validated numeric command-line option types: use them as ``type=`` of every numeric option.

Each factory returns an argparse type that parses the text, refuses NaN, infinities and values
outside the stated range, and names the range in its one-line message (argparse reports it as
``wristmark CMD: error: argument --x: ...`` with exit status 2). Example::

    p.add_argument("--dt", type=float_in(1e-3, 1.0), metavar="S", help="control cycle [s]")
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def _fmt(x: float) -> str:
    return f"{x:g}"


def float_in(lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False,
             hi_open: bool = False) -> Callable[[str], float]:
    """A finite float in [lo, hi] (``lo_open``/``hi_open``: exclude that end)."""

    def parse(text: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        span = f"{left}{_fmt(lo)}, {_fmt(hi)}{right}"
        if not math.isfinite(x):
            raise argparse.ArgumentTypeError(f"'{text}' is not a finite number (expected one in {span})")
        if x < lo or x > hi or (lo_open and x == lo) or (hi_open and x == hi):
            raise argparse.ArgumentTypeError(f"{text} is outside {span}")
        return x

    parse.__name__ = "number"  # argparse names the type in its messages
    return parse


def positive_float(hi: float = math.inf) -> Callable[[str], float]:
    """A finite float in (0, hi]."""
    return float_in(0.0, hi, lo_open=True)


def nonnegative_float(hi: float = math.inf) -> Callable[[str], float]:
    """A finite float in [0, hi]."""
    return float_in(0.0, hi)


def finite_float() -> Callable[[str], float]:
    """Any finite float."""
    return float_in()


def int_in(lo: int, hi: int) -> Callable[[str], int]:
    """An integer in [lo, hi]."""

    def parse(text: str) -> int:
        try:
            x = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
        if x < lo or x > hi:
            raise argparse.ArgumentTypeError(f"{text} is outside [{lo}, {hi}]")
        return x

    parse.__name__ = "integer"
    return parse


SEED_MAX = 2**32 - 1
"""Largest seed numpy's generators take."""


def seed_int() -> Callable[[str], int]:
    """A random seed in [0, 2^32 - 1]."""
    return int_in(0, SEED_MAX)
