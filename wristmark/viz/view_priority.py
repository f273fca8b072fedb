"""The view's processes (Meshcat server, live drawer) run below the servo loop's priority."""

from __future__ import annotations

import os

VIEW_NICENESS = 5  # added to the nice value of the view's processes


def lower_priority() -> None:
    """The view is best effort: under CPU contention the servo loop goes first."""
    try:
        os.nice(VIEW_NICENESS)
    except OSError:
        pass
