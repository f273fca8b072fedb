"""Validated numeric command-line option types: use them as ``type=`` of every numeric option.

Each factory returns an argparse type that parses the text, refuses NaN, infinities and values
outside the stated range, and names the range in its one-line message (argparse reports it as
``wristmark CMD: error: argument --x: ...`` with exit status 2). Example::

    p.add_argument("--dt", type=float_in(1e-3, 1.0), metavar="S", help="control cycle [s]")

Every type made here carries its range as ``validated_range`` (tests/cli/test_cli_options.py finds
every numeric option of every command and fails on one without it).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def _fmt(x: float) -> str:
    return f"{x:g}"


def _validated(parse: Callable[[str], T], span: str, lo: float, hi: float) -> Callable[[str], T]:
    """Mark ``parse`` as a validated option type accepting values in ``span`` (bounds lo, hi)."""
    parse.validated_range = span  # type: ignore[attr-defined]
    parse.bounds = (lo, hi)  # type: ignore[attr-defined]
    return parse


def float_in(lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False,
             hi_open: bool = False) -> Callable[[str], float]:
    """A finite float in [lo, hi] (``lo_open``/``hi_open``: exclude that end)."""
    span = f"{'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}{')' if hi_open else ']'}"

    def parse(text: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number (expected one in {span})") from None
        if not math.isfinite(x):
            raise argparse.ArgumentTypeError(f"'{text}' is not a finite number (expected one in {span})")
        if x < lo or x > hi or (lo_open and x == lo) or (hi_open and x == hi):
            raise argparse.ArgumentTypeError(f"{text} is outside {span}")
        return x

    parse.__name__ = "number"  # argparse names the type in its messages
    return _validated(parse, span, lo, hi)


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
            raise argparse.ArgumentTypeError(f"'{text}' is not an integer (expected one in [{lo}, {hi}])") from None
        if x < lo or x > hi:
            raise argparse.ArgumentTypeError(f"{text} is outside [{lo}, {hi}]")
        return x

    parse.__name__ = "integer"
    return _validated(parse, f"[{lo}, {hi}]", lo, hi)


SEED_MAX = 2**32 - 1
"""Largest seed numpy's generators take."""


def seed_int() -> Callable[[str], int]:
    """A random seed in [0, 2^32 - 1]."""
    return int_in(0, SEED_MAX)


# -- ranges shared by the commands' options (SI units) ------------------------------------------
PSI_ABS_MAX = 100.0  # [rad or m] sanity bound on each configuration entry (limits are checked later)
MAX_POINT_M = 10.0  # [m] sanity bound on a point's coordinates in {w}
MIN_CONTROL_DT, MAX_CONTROL_DT = 1e-3, 1.0  # [s] servo cycle (the plant steps at 1 ms)
MIN_IMAGE_SCALE, MAX_IMAGE_SCALE = 0.05, 4.0  # rendering scale of the calibrated image size
MAX_DURATION_S = 3600.0  # [s] of a trajectory or experiment
MAX_SETTLE_S = 600.0  # [s] closed-loop approach to a trajectory's start
MAX_HOLD_S = 86400.0  # [s] serving or holding a view
MAX_TIMEOUT_S = 60.0  # [s] reply timeouts and watchdogs
MIN_BAUD, MAX_BAUD = 50, 4_000_000  # serial baud rates
MAX_POSITIONS = 1000  # accuracy experiment positions
MAX_TIP_FORCE_N = 1.0  # [N] tip load of the load sweep
MAX_PAIRS = 10000  # rendered stereo pairs
MAX_BLUR_PX = 100.0  # [px] motion blur length
MAX_RMS_PX = 100.0  # [px] accepted reprojection RMS
MAX_LINKS = 100  # pseudo-rigid links per URDF segment
MAX_FRAMES = 100_000  # key frames of a replay
