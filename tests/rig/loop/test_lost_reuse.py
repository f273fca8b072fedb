"""rig ``reuse_lost``: a frame that shows no marker steps the controller on the last accepted
measurement (moved on by the delay compensation, at most ``reuse_measurement_age`` old), on the
simulated clock too, instead of holding the arm: a held arm falls behind the path by its speed x
the cycle for every lost cycle."""

from __future__ import annotations

import dataclasses

import numpy as np

from tests.rig.loop.test_servo_loop import RIG, P, _line, _loop, _plant
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.rig.recording.run_log import RunLog
from wristmark.sim.plant import TruePlant
from wristmark.sim.truth_sensor import NoisyTruthSensor


class _Gap:
    """Real measurements, except ``gap`` cycles from cycle ``lose_at`` on: the marker not found."""

    def __init__(self, plant: TruePlant, lose_at: int, gap: int) -> None:
        self.inner = NoisyTruthSensor(plant, 1e-5, seed=3)
        self.n = 0
        self.lose_at, self.gap = lose_at, gap

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        self.n += 1
        if self.lose_at <= self.n < self.lose_at + self.gap:
            return TipMeasurement(False, None, "marker not found")
        return self.inner.measure(frame)  # type: ignore[arg-type]


def _walk(reuse_lost: bool, gap: int, age: float = 0.3) -> tuple[RunLog, object]:
    plant = _plant()
    rig = dataclasses.replace(RIG, reuse_lost=reuse_lost, reuse_measurement_age=age, max_lost_cycles=10,
                              lost_dither=0.0)
    loop, _ = _loop(_Gap(plant, lose_at=6, gap=gap), True, rig=rig, plant=plant)
    log = RunLog()
    stats = loop.run(_line(), "closed", True, log, settle=0.0)
    return log, stats


def _lost_stretch_error(log: RunLog) -> float:
    """The largest true tip error [m] from the first lost (or rejected) cycle to two cycles after the last."""
    ok = [r.meas_ok for r in log.records]
    first, last = ok.index(False), len(ok) - 1 - ok[::-1].index(False)
    return max(float(np.linalg.norm(r.p_true - r.p_des)) for r in log.records[first:last + 3])


def test_a_lost_marker_steps_on_the_last_measurement_instead_of_holding() -> None:
    held_log, held = _walk(False, gap=3)
    log, stats = _walk(True, gap=3)
    lost = [i for i, r in enumerate(log.records) if not r.meas_ok]
    assert len(lost) == 3 and stats.lost == 3 and stats.reused == 3  # type: ignore[attr-defined]
    # every lost cycle moved the command on along the path (holding, it stays)
    for i in lost:
        assert not np.array_equal(log.records[i].psi_cmd, log.records[i - 1].psi_cmd)
        assert np.array_equal(held_log.records[i].psi_cmd, held_log.records[i - 1].psi_cmd)
    assert held.reused == 0  # type: ignore[attr-defined]
    # holding, the tip falls 0.6 mm behind per lost cycle at 10 mm/s; stepping on, it keeps up
    assert _lost_stretch_error(held_log) > 1.0e-3
    assert _lost_stretch_error(log) < 0.5 * _lost_stretch_error(held_log)


def test_a_lost_marker_holds_the_arm_once_the_last_measurement_is_too_old() -> None:
    log, stats = _walk(True, gap=6, age=0.15)
    lost = [i for i, r in enumerate(log.records) if not r.meas_ok]
    assert len(lost) == 6
    assert stats.reused == 2  # type: ignore[attr-defined]  # 0.06 and 0.12 s old; 0.18 s is too old
    moved = [not np.array_equal(log.records[i].psi_cmd, log.records[i - 1].psi_cmd) for i in lost]
    assert moved == [True, True, False, False, False, False]


class _Outliers(_Gap):
    """As :class:`_Gap`, but the ``gap`` cycles measure the tip 10 mm off (the jump gate, 4 mm,
    rejects them)."""

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        meas = self.inner.measure(frame)  # type: ignore[arg-type]
        self.n += 1
        if self.lose_at <= self.n < self.lose_at + self.gap and meas.p_world is not None:
            return dataclasses.replace(meas, p_world=meas.p_world + np.array([0.01, 0.0, 0.0]))
        return meas


def _outlier_walk(reuse_lost: bool) -> tuple[RunLog, object]:
    plant = _plant()
    rig = dataclasses.replace(RIG, reuse_lost=reuse_lost, reuse_measurement_age=0.3, lost_dither=0.0)
    loop, _ = _loop(_Outliers(plant, lose_at=6, gap=3), True, rig=rig, plant=plant)
    log = RunLog()
    return log, loop.run(_line(), "closed", True, log, settle=0.0)


def test_a_rejected_measurement_steps_on_the_last_accepted_one() -> None:
    held_log, held = _outlier_walk(False)
    log, stats = _outlier_walk(True)
    rejected = [i for i, r in enumerate(log.records) if r.rejected]
    assert len(rejected) == 3 and stats.rejected == 3 and stats.reused == 3  # type: ignore[attr-defined]
    assert held.reused == 0  # type: ignore[attr-defined]
    for i in rejected:
        assert not np.array_equal(log.records[i].psi_cmd, log.records[i - 1].psi_cmd)
    held_rejected = [i for i, r in enumerate(held_log.records) if r.rejected]
    assert held_rejected  # (the jump gate widens with each: the held arm's last outlier may pass it)
    for i in held_rejected:
        assert np.array_equal(held_log.records[i].psi_cmd, held_log.records[i - 1].psi_cmd)
    # the 10 mm outliers never drove the arm, and it did not fall behind while they came
    assert _lost_stretch_error(held_log) > 1.0e-3
    assert _lost_stretch_error(log) < 0.5 * _lost_stretch_error(held_log)


class _LostThenOutlier(_Gap):
    """As :class:`_Gap` (``gap`` cycles without the marker), then one measurement 8 mm off."""

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        meas = self.inner.measure(frame)  # type: ignore[arg-type]
        self.n += 1
        if self.lose_at <= self.n < self.lose_at + self.gap:
            return TipMeasurement(False, None, "marker not found")
        if self.n == self.lose_at + self.gap and meas.p_world is not None:
            return dataclasses.replace(meas, p_world=meas.p_world + np.array([0.0, 0.008, 0.0]))
        return meas


def test_after_cycles_that_stepped_on_the_last_measurement_the_jump_gate_does_not_widen() -> None:
    """Three lost cycles that held the arm widen the 4 mm jump gate to 16 mm (an 8 mm wrong pose
    passes and drives the arm); three that stepped on the last measurement count the jump from
    where it predicts the tip, at 4 mm."""
    results = {}
    for reuse in (False, True):
        plant = _plant()
        rig = dataclasses.replace(RIG, reuse_lost=reuse, reuse_measurement_age=0.3, lost_dither=0.0)
        loop, _ = _loop(_LostThenOutlier(plant, lose_at=6, gap=3), True, rig=rig, plant=plant)
        log = RunLog()
        stats = loop.run(_line(), "closed", True, log, settle=0.0)
        results[reuse] = (log.records[8].meas_ok, log.records[8].rejected, stats.rejected)  # type: ignore[attr-defined]
    assert results[False][:2] == (True, False)  # the wrong pose accepted: the arm chases it
    assert results[True] == (False, True, 1)  # rejected, the only one


def test_a_reused_measurements_orientation_is_turned_on_with_its_tip() -> None:
    """A cycle that steps on the last measurement asks the controller for the orientation the
    model turned it to since its capture, not for the same turn again (a reused measurement's
    stale rotation, applied on every cycle without a frame, made an arm holding its orientation
    over a slow camera oscillate, tests/sim/test_scene_lab.py)."""
    plant = _plant()
    rig = dataclasses.replace(RIG, reuse_lost=True, reuse_measurement_age=0.3, max_lost_cycles=10, lost_dither=0.0)
    loop, _ = _loop(_Gap(plant, lose_at=6, gap=3), True, rig=rig, plant=plant)
    assert loop.controller is not None and loop.delay is not None
    asked: list[tuple[object, ...]] = []
    step = loop.controller.step

    def spy(*args: object, **kwargs: object) -> object:
        asked.append(args)
        return step(*args, **kwargs)  # type: ignore[arg-type]

    loop.controller.step = spy  # type: ignore[method-assign]
    log = RunLog()
    loop.run(_line().with_orientation("hold", P), "closed", True, log, settle=0.0)
    lost = [i for i, r in enumerate(log.records) if not r.meas_ok]
    assert lost == [5, 6, 7] and len(asked) == len(log.records)
    last = log.records[4]  # the measurement the lost cycles step on
    assert last.R_est is not None
    turned = []
    for i in lost:
        orient = asked[i][-1]
        assert orient is not None
        R = np.asarray(orient.R_meas)  # type: ignore[attr-defined]
        angle = np.degrees(np.arccos(np.clip((np.trace(R @ np.asarray(last.R_est).T) - 1) / 2, -1, 1)))
        turned.append(angle)
    # each lost cycle's rotation is the last one turned on by the commands since: more each cycle
    assert turned[0] > 1e-3 and turned[1] > turned[0] and turned[2] > turned[1], turned
