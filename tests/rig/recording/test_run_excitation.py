"""A servo run's log.csv as an identification's excitation: the actuators' columns written by
RunLog are read back, each tracked tip gets the encoders interpolated to its capture, phases
that restart their clock follow each other, and a log without the columns is refused."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams
from wristmark.rig.recording.run_excitation import excitation_from_run
from wristmark.rig.recording.run_log import CycleRecord, RunLog

ARM = RobotParams()
NAN3 = np.full(3, math.nan)


def _record(t: float, phase: str, enc: np.ndarray, tip: np.ndarray | None, capture: float) -> CycleRecord:
    return CycleRecord(t=t, phase=phase, p_des=NAN3, p_cmd=NAN3, p_est=tip, p_true=NAN3, p_trk=NAN3,
                       psi_cmd=np.full(6, 0.1), psi_true=np.full(6, math.nan), meas_ok=tip is not None,
                       rejected=False, vision_ms=1.0, ctrl_us=1.0, t_capture=capture, t_act=t,
                       act_cmd=enc + 1e-4, act_meas=enc)


def test_tips_get_the_encoders_at_their_capture_and_phases_follow_each_other(tmp_path: Path) -> None:
    log = RunLog.for_arm(ARM)
    slope = np.array([0.01, 0.001, 0.002, -0.002, 0.003, -0.003])
    for phase in ("open_loop", "closed_loop"):  # each phase's clock starts again at 0
        for k in range(10):
            t = 0.06 * k
            tip = np.array([0.0, 0.0, 0.1 + k]) if k % 3 == 1 else None
            log.add(_record(t, phase, slope * t, tip, t - 0.045 if tip is not None else math.nan))
    log.write_csv(tmp_path / "log.csv")

    data = excitation_from_run(tmp_path, ARM)
    assert np.all(np.diff(data.times) > 0)  # one clock: the second phase after the first
    assert data.times[-1] == pytest.approx(0.06 * 9 * 2 + 0.06)
    assert data.sample_index.size == 6 and data.tips[:, 2] == pytest.approx([1.1, 4.1, 7.1] * 2)
    first = data.sample_index[0]
    assert data.times[first] == pytest.approx(0.06 - 0.045)
    assert data.encoders[first] == pytest.approx(slope * (0.06 - 0.045))  # interpolated to the capture
    assert data.targets[first] == pytest.approx(1e-4 + np.zeros(6))  # the target in force then (the t = 0 one)


def test_a_log_without_the_actuators_columns_is_refused(tmp_path: Path) -> None:
    (tmp_path / "log.csv").write_text("t,phase,psi_cmd_0,psi_true_0,p_est_x\n0.0,servo,0.1,,0.05\n")
    with pytest.raises(InputError, match="no column 't_act'"):
        excitation_from_run(tmp_path, ARM)
