"""The virtual lab's camera runs on a fixed frame clock: frame k starts k periods after the
first (a wake-up's lateness does not accumulate), so a host can lock its cycle to the frames;
a frame slower than the period restarts the clock."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.sim.virtual_lab import next_frame_start

PERIOD = 0.06  # [s]


def test_late_wake_ups_do_not_move_the_frame_clock() -> None:
    rng = np.random.default_rng(0)
    t_next, starts = 10.0, []
    for _ in range(200):
        woke = t_next + rng.uniform(0.0, 0.002)  # each wake-up up to 2 ms late ...
        starts.append(woke)
        t_next = next_frame_start(t_next, PERIOD, woke + 0.02)  # ... and 20 ms of rendering
    late = np.array(starts) - (10.0 + PERIOD * np.arange(200))
    assert np.all((late >= 0) & (late <= 0.002)), late  # on the clock after 200 frames (12 s)


def test_a_frame_slower_than_the_period_restarts_the_clock() -> None:
    assert next_frame_start(1.0, PERIOD, 1.2) == pytest.approx(1.2)  # at once, from now
    assert next_frame_start(1.2, PERIOD, 1.21) == pytest.approx(1.26)  # then one period on
