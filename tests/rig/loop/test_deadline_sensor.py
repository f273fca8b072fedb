"""A measurement that takes longer than the cycle allows is given up (the loop holds the arm for
that cycle) while the worker finishes; a frame arriving while it is still busy is not measured."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.errors import ConfigError
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.tip_sensors import DeadlineTipSensor, TipMeasurement

_EMPTY = np.zeros((1, 1), np.uint8)


def _frame(i: int) -> StereoFrame:
    return StereoFrame(_EMPTY, _EMPTY, float(i), i)


class _Slow:
    """Takes ``delay[i]`` s for frame i; records which frames it finished."""

    def __init__(self, delays: dict[int, float]) -> None:
        self.delays = delays
        self.done: list[int] = []
        self.threads: set[str] = set()

    def measure(self, frame: StereoFrame, axis_hint_world: np.ndarray | None = None) -> TipMeasurement:
        self.threads.add(threading.current_thread().name)
        time.sleep(self.delays.get(frame.index, 0.0))
        self.done.append(frame.index)
        return TipMeasurement(True, np.full(3, float(frame.index)), t_capture=frame.t_capture, frame_index=frame.index)


@pytest.mark.wallclock
def test_a_slow_measurement_is_given_up_at_the_budget_and_finishes_in_the_background() -> None:
    inner = _Slow({1: 0.6})
    sensor = DeadlineTipSensor(inner, budget=0.1)
    try:
        fast = sensor.measure(_frame(0))
        assert fast.ok and fast.frame_index == 0 and np.all(fast.p_world == 0.0)
        t0 = time.perf_counter()
        slow = sensor.measure(_frame(1))
        waited = time.perf_counter() - t0
        assert not slow.ok and "longer than 100 ms" in slow.reason and slow.frame_index == 1
        assert 0.09 <= waited < 0.4  # the caller got its answer at the budget, not after 0.6 s
        busy = sensor.measure(_frame(2))  # the worker is still on frame 1
        assert not busy.ok and "still busy" in busy.reason and 2 not in inner.done
        time.sleep(0.7)
        assert inner.done == [0, 1]  # frame 1 was finished (the tracker learns where the marker is)
        again = sensor.measure(_frame(3))
        assert again.ok and again.frame_index == 3
        assert sensor.late == 1 and all(name.startswith("tip-sensor") for name in inner.threads)
    finally:
        sensor.close()


def test_the_budget_and_the_frame_wait_keep_a_cycle_within_the_watchdog() -> None:
    with pytest.raises(ConfigError, match="tracking_budget"):
        RigConfig(tracking_budget=0.0).validate()
    with pytest.raises(ConfigError, match="250 ms watchdog"):
        RigConfig(frame_wait=0.05, tracking_budget=0.2).validate()
    RigConfig().validate()
