"""Error statistics and corner overshoot."""

import numpy as np
import pytest

from wristmark.rig.loop.metrics import corner_overshoot, error_stats, estimate_errors, tracking_errors
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.rig.targets.trajectories import Trajectory


def _rec(t: float, p_des, p_true) -> CycleRecord:
    z = np.zeros(6)
    return CycleRecord(t, "x", np.asarray(p_des, float), np.zeros(3), None, np.asarray(p_true, float),
                       np.asarray(p_true, float), z, z, True, False, 0.0, 0.0)


def test_error_stats_in_mm() -> None:
    st = error_stats(np.array([0.001, 0.003, np.nan]))
    assert st.mean_mm == pytest.approx(2.0)
    assert st.max_mm == pytest.approx(3.0)
    assert st.n == 2


def _corner_run(extra: float) -> tuple[list[CycleRecord], Trajectory]:
    traj = Trajectory(np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 0]]), 1.0)
    recs = []
    for k in range(21):
        t = 0.1 * k
        p, _ = traj.sample(t)
        bump = extra if 1.0 < t < 1.5 else 0.0
        recs.append(_rec(t, p, (p[0] + bump, p[1], 0.0)))
    return recs, traj


def test_overshoot_detects_passing_a_corner() -> None:
    recs, traj = _corner_run(0.0002)
    over = corner_overshoot(recs, traj.waypoints, traj.times, window=1.0)
    assert over.size == 1
    assert over[0] == pytest.approx(0.0002, abs=1e-9)
    assert tracking_errors(recs, "p_true").max() == pytest.approx(0.0002)


def test_no_overshoot_when_the_tip_turns_at_the_corner() -> None:
    recs, traj = _corner_run(0.0)
    assert corner_overshoot(recs, traj.waypoints, traj.times)[0] == pytest.approx(0.0, abs=1e-12)


def test_estimate_errors_compare_vision_with_the_true_tip_not_the_desired() -> None:
    import dataclasses

    a = _rec(0.0, [0.0, 0, 0], [0.001, 0, 0])
    b = dataclasses.replace(a, p_est=np.array([0.001, 0.0, 0.0005]))
    e = estimate_errors([a, b])
    assert np.isnan(e[0])  # no estimate
    assert e[1] == pytest.approx(0.0005)
