"""The servo loop's cycle locked to a free-running camera's frames (wall clock only).

A camera that delivers one frame per control cycle (its period equals the loop's ``control_dt``,
or divides it) captures at a fixed phase of the loop's cycle, but that phase is whatever the two
clocks' start gave: the measurement's age at the cycle's start, how long the cycle waits for
its frame and when its command goes out all depend on it. :class:`FramePhaseLock` shifts the
loop's cycle grid so that the frames are captured (or arrive at the host: the loop chooses
which instant it observes) ``target`` seconds after each cycle's nominal start: a first-order
(proportional) phase-locked loop on the observed offset, limited to ``MAX_STEP`` per cycle so
that a late frame or a stamp's jitter never jolts the cycle. Locked on the arrival, every
cycle's command goes out at the same instant of the cycle (arrival + the host's work) whatever
the frames' transport.
"""

from __future__ import annotations

import math

GAIN = 0.3  # fraction of the phase error corrected per observed frame
MAX_STEP = 0.005  # [s] largest change of the cycle grid's shift per cycle


class FramePhaseLock:
    """Shift [s] of the loop's cycle grid that makes frames be captured (or arrive) ``target``
    [s] after a cycle's nominal start; ``period``: the loop's cycle [s], modulo which the phase error is
    taken (a late frame handed to the next cycle is a cycle early, not a huge error);
    ``offsets`` lists each observed instant - nominal start [s]."""

    def __init__(self, target: float, period: float) -> None:
        self.target = float(target)
        self.period = float(period)
        self.shift = 0.0
        self.offsets: list[float] = []

    def observe(self, offset: float) -> None:
        """The cycle's frame was captured (or arrived) ``offset`` [s] after the current cycle's
        nominal start (negative: before it): move the grid by a bounded fraction of the phase error."""
        if not math.isfinite(offset):
            return
        self.offsets.append(offset)
        half = 0.5 * self.period
        error = (offset - self.target + half) % self.period - half  # in [-period/2, period/2)
        step = GAIN * error
        self.shift += min(max(step, -MAX_STEP), MAX_STEP)
