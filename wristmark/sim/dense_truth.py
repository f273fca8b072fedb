"""The virtual lab's true tip sampled densely in time, not only at its rendered frames.

The frames' truth (``--truth-out``: one row per rendered frame) is 25-40 ms apart at the lab's
frame rates, and the true arm does not move linearly in between: every 60 ms it gets a new
target and follows it through the actuators' first-order lag, so a true tip interpolated
linearly between frames at a control cycle's instant is off by up to ~0.1 mm (a 0.6 mm step
through a 40 ms lag, frames 40 ms apart). The in-process bench evaluates its truth exactly at
each cycle. :class:`DenseTruthArm` wraps the lab's arm and writes the true tip after every
advance of the arm by the actuator-box emulator (its ~10 ms polls and every packet), at most
every ``min_interval`` [s], on the emulator's clock (``time.monotonic()`` [s]), in the
``--truth-out`` format (``t,tip_x,tip_y,tip_z``, {w} [m]).
"""

from __future__ import annotations

from pathlib import Path
from typing import IO

import numpy as np

from wristmark.sim.locked_arm import LockedArm

TRUTH_HEADER = "t,tip_x,tip_y,tip_z"


class DenseTruthArm(LockedArm):
    """A :class:`LockedArm` that logs its true tip after each advance (see the module docstring).

    Call :meth:`start` with the emulator clock's time of the arm's current time (the two then
    advance together: the emulator advances the arm by exactly the time its clock ran) and the
    CSV path; rows are kept in memory by the box's thread (a file write could block it) and
    written by :meth:`flush`; :meth:`close` flushes and closes the file."""

    def __init__(self, arm: LockedArm, min_interval: float = 0.004) -> None:
        super().__init__(arm.arm, arm.lock)
        self.min_interval = float(min_interval)
        self._file: IO[str] | None = None
        self._offset = 0.0
        self._t_last = -np.inf
        self._pending: list[str] = []
        self.rows = 0

    def start(self, t_clock_now: float, path: str | Path) -> None:
        """Begin logging to ``path``; ``t_clock_now``: the emulator clock [s] at the arm's current time."""
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        with self.lock:
            self._offset = float(t_clock_now) - float(self.arm.time)
            self._file = open(p, "w")
            self._file.write(TRUTH_HEADER + "\n")
            self._write()
        self.flush()

    def _write(self) -> None:
        t = self._offset + float(self.arm.time)
        true_tip = getattr(self.arm, "true_tip", None)  # TruePlant's: without the shape's points
        tip = true_tip() if callable(true_tip) else self.arm.true_shape().tip
        x, y, z = (float(v) for v in tip)
        self._pending.append(f"{t:.6f},{x:.9g},{y:.9g},{z:.9g}\n")  # no file I/O in the box's thread
        self._t_last = t
        self.rows += 1

    def flush(self) -> None:
        """Write the rows logged so far to the file (from any thread but the box's: the lab's
        camera thread after each frame, and :meth:`close`)."""
        with self.lock:
            rows, self._pending = self._pending, []
            f = self._file
        if f is not None and rows:
            f.write("".join(rows))
            f.flush()

    def advance(self, dt: float) -> None:
        """Advance by ``dt`` [s], then log the true tip when ``min_interval`` has passed."""
        with self.lock:
            self.arm.advance(dt)
            if self._file is not None and self._offset + self.arm.time - self._t_last >= self.min_interval:
                self._write()

    def close(self) -> None:
        """Write what is pending and stop logging (idempotent)."""
        self.flush()
        with self.lock:
            if self._file is not None:
                self._file.close()
                self._file = None
