"""Why a loop that stays without an accepted measurement stops: "camera stalled" only when no new
frame came in the whole lost run; frames that did not show the marker make it "marker lost",
whatever the last cycle lacked (an arm set stops every arm on a stall, but only the lost arm on
a lost marker: rig.loop.arm_set_session)."""

from __future__ import annotations

import dataclasses

import pytest

from tests.rig.loop.test_servo_loop import RIG, _line, _loop, _plant
from wristmark.rig.loop.frame_feed import SynchronousFeed
from wristmark.rig.loop.servo_cycle import CameraStalledError, MarkerLostError
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.rig.recording.run_log import RunLog
from wristmark.sim.truth_sensor import NoisyTruthSensor

MAX_LOST = 5


class _Blind:
    """Real measurements for the first ``seen`` frames, then the marker never found."""

    def __init__(self, inner: NoisyTruthSensor, seen: int) -> None:
        self.inner, self.seen, self.n = inner, seen, 0

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        self.n += 1
        if self.n > self.seen:
            return TipMeasurement(False, None, "marker not found")
        return self.inner.measure(frame)  # type: ignore[arg-type]


class _Gappy:
    """A feed that hands out no frame on the cycles (1-based) in ``missing``."""

    def __init__(self, inner: SynchronousFeed, missing: set[int]) -> None:
        self.inner, self.missing, self.n = inner, missing, 0
        self.name, self.last_arrival = inner.name, inner.last_arrival

    def take(self, fresh_after: float = float("-inf"), wait_until: float = float("-inf")) -> object:
        self.n += 1
        frame = self.inner.take(fresh_after, wait_until)
        return None if self.n in self.missing else frame

    @property
    def dropped(self) -> int:
        return self.inner.dropped

    def close(self) -> None:
        self.inner.close()


def _run(seen: int, missing: set[int]) -> BaseException:
    plant = _plant()
    rig = dataclasses.replace(RIG, max_lost_cycles=MAX_LOST, lost_dither=0.0, reuse_lost=False,
                              open_loop_on_lost=0.0)
    loop, _ = _loop(_Blind(NoisyTruthSensor(plant, 1e-5, seed=3), seen), True, rig=rig, plant=plant)
    assert isinstance(loop.frames, SynchronousFeed)
    loop.frames = _Gappy(loop.frames, missing)  # type: ignore[assignment]
    with pytest.raises(MarkerLostError) as info:
        loop.run(_line(), "closed", True, RunLog(), settle=0.0)
    return info.value


def test_a_lost_marker_whose_last_cycle_has_no_frame_is_still_a_lost_marker() -> None:
    # seen for 4 frames, then lost: the cycle that exceeds MAX_LOST (the 10th) and one before it lack a frame
    e = _run(4, {7, 10})
    assert not isinstance(e, CameraStalledError)
    assert "marker lost for 6 cycles" in str(e) and "(marker not found)" in str(e), str(e)


def test_no_frame_in_the_whole_lost_run_is_a_camera_stall() -> None:
    e = _run(100, set(range(5, 40)))
    assert isinstance(e, CameraStalledError)
    assert "camera stalled: no new frame" in str(e) and "for 6 cycles" in str(e), str(e)
