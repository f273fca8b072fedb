"""rig/loop/servo_summary.py: the cycle timing of a run's log."""

from __future__ import annotations

import numpy as np

from wristmark.rig.loop.servo_summary import cycle_timing
from wristmark.rig.recording.run_log import CycleRecord

DT = 0.06


def _records(t_nominal: np.ndarray, late: np.ndarray) -> list[CycleRecord]:
    z = np.zeros(3)
    return [CycleRecord(t=float(t), phase="servo", p_des=z, p_cmd=z, p_est=z, p_true=z, p_trk=z, psi_cmd=np.zeros(6),
                        psi_true=np.zeros(6), meas_ok=True, rejected=False, vision_ms=4.0, ctrl_us=500.0,
                        t_wall=float(100.0 + t + d)) for t, d in zip(t_nominal, late)]


def test_skipped_cycles_and_another_arms_probe_between_are_no_jitter() -> None:
    """Cycles 0-9, 12-19 (two skipped) and 60-79 (another arm probed in between), each started
    1-3 ms after its nominal time: the jitter is that spread, not the gaps."""
    k = np.r_[np.arange(10), np.arange(12, 20), np.arange(60, 80)]
    late = 0.001 + 0.002 * (k % 2)
    timing = cycle_timing(_records(DT * k, late), DT)
    assert timing["jitter_ms"]["max_ms"] < 1.01 and timing["jitter_ms"]["n"] == k.size
    assert abs(timing["period_median_ms"] - 1000 * DT) < 2.01


def test_a_late_cycle_is_jitter() -> None:
    k = np.arange(30)
    late = np.where(k == 17, 0.025, 0.002)
    timing = cycle_timing(_records(DT * k, late), DT)
    assert abs(timing["jitter_ms"]["max_ms"] - 23.0) < 0.01
