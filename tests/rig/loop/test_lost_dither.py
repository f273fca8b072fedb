"""The servo loop's dither when the marker is lost while the arm holds (rig ``lost_dither``):
bounded, logged, never adding up, and it gives a view-dependent loss a way out."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.rig.loop.test_servo_loop import RIG, _Blinking, _line, _loop, _plant
from wristmark.models.kinematics import tip_position
from wristmark.models.robot_params import RobotParams
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.servo_loop import MarkerLostError
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.rig.recording.run_log import RunLog
from wristmark.sim.plant import TruePlant
from wristmark.sim.truth_sensor import NoisyTruthSensor

P = RobotParams()
DITHER = dataclasses.replace(RIG, lost_dither=0.001, lost_dither_after=2, max_lost_cycles=8)


def test_a_lost_marker_dithers_around_the_held_command_then_stops() -> None:
    plant = _plant()
    loop, _ = _loop(_Blinking(plant, lose_at=8), True, rig=DITHER, plant=plant)
    log = RunLog()
    with pytest.raises(MarkerLostError, match="marker lost") as err:
        loop.run(_line(), "closed", True, log, settle=0.0)
    lost = [r for r in log.records if not r.meas_ok]
    assert len(lost) == DITHER.max_lost_cycles + 1
    held = lost[0].psi_cmd
    # the first lost_dither_after - 1 lost cycles hold; then every lost cycle but the stopping one moves
    assert all(np.array_equal(held, r.psi_cmd) for r in lost[: DITHER.lost_dither_after - 1])
    moved = lost[DITHER.lost_dither_after - 1 : -1]
    assert all(not np.array_equal(held, r.psi_cmd) for r in moved)
    tip0 = tip_position(P, held)
    steps = [float(np.linalg.norm(tip_position(P, r.psi_cmd) - tip0)) for r in moved]
    assert max(steps) <= DITHER.lost_dither * 1.05  # bounded around the held command: never adds up
    assert min(steps) >= 0.5 * DITHER.lost_dither
    assert np.count_nonzero(np.any(np.diff([r.psi_cmd for r in moved], axis=0) != 0, axis=1)) == len(moved) - 1
    assert err.value.stats is not None and err.value.stats.dithers == len(moved)


def test_no_dither_when_off_or_for_a_rejected_measurement() -> None:
    plant = _plant()
    off = dataclasses.replace(DITHER, lost_dither=0.0)
    loop, _ = _loop(_Blinking(plant, lose_at=8), True, rig=off, plant=plant)
    log = RunLog()
    with pytest.raises(MarkerLostError) as err:
        loop.run(_line(), "closed", True, log, settle=0.0)
    lost = [r for r in log.records if not r.meas_ok]
    assert all(np.array_equal(lost[0].psi_cmd, r.psi_cmd) for r in lost)
    assert err.value.stats is not None and err.value.stats.dithers == 0


class _StuckView:
    """Real measurements, except from cycle ``lose_at`` on: the marker cannot be read for 3
    cycles, and then as long as the true tip moves less than 0.2 mm per cycle (a still arm keeps
    a highlight over the corners where it is)."""

    def __init__(self, plant: TruePlant, lose_at: int) -> None:
        self.plant = plant
        self.inner = NoisyTruthSensor(plant, 1e-5, seed=3)
        self.n = 0
        self.lose_at = lose_at
        self.prev: np.ndarray | None = None
        self.lost = 0
        self.blind = False

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        self.n += 1
        tip = self.plant.true_shape().tip
        still = self.prev is not None and float(np.linalg.norm(tip - self.prev)) < 2e-4
        self.prev = tip
        self.blind = self.lose_at <= self.n < self.lose_at + 3 or (self.blind and still)
        if self.blind:
            self.lost += 1
            return TipMeasurement(False, None, "too few marker corners (left 0, right 5)")
        return self.inner.measure(frame)  # type: ignore[arg-type]


@pytest.mark.parametrize("dither", [0.0, 0.001])
def test_the_dither_gets_the_loop_past_a_pose_it_cannot_see(dither: float) -> None:
    plant = _plant()
    sensor = _StuckView(plant, lose_at=5)
    rig: RigConfig = dataclasses.replace(DITHER, lost_dither=dither, max_lost_cycles=12)
    loop, _ = _loop(sensor, True, rig=rig, plant=plant)
    log = RunLog()
    # the arm holds at the pose it cannot see: without the dither the loop stops there
    line = _line()
    if dither == 0:
        with pytest.raises(MarkerLostError):
            loop.run(line, "closed", True, log, settle=0.0)
        return
    loop.run(line, "closed", True, log, settle=0.0)
    assert sensor.lost >= rig.lost_dither_after
    assert log.records[-1].meas_ok
