"""Random format-2 robot files (hypothesis: 1-4 segments, random stems, every actuation type,
planar or not), each written to YAML and loaded: the closed form equals the pseudo-rigid model
through Pinocchio, and the actuation map round-trips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.models.arm_strategies import psis, robot_files, spec_of
from wristmark.models.arm_actuation import arm_actuators, arm_psi_from_actuators
from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian
from wristmark.models.arm_pinocchio import PinocchioAnyArm

SEEDED = settings(max_examples=40, derandomize=True, deadline=None,
                  suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@SEEDED
@given(robot=robot_files(), links=st.integers(1, 4), data=st.data())
def test_random_robot_files_closed_form_vs_pinocchio_and_round_trip(tmp_path: Path, robot: dict,  # type: ignore[type-arg]
                                                                    links: int, data: st.DataObject) -> None:
    spec = spec_of(robot, tmp_path)
    assert spec.n == len(spec.stem) + sum(1 if s.get("planar") is not None else 2 for s in robot["segments"])
    arm = PinocchioAnyArm(spec, links)
    for psi in (data.draw(psis(spec)), data.draw(psis(spec))):
        got, ref = arm.forward(psi), arm_frames(spec, psi)
        for name in ("T_world_base", "T_world_end", "T_world_marker", "T_world_tip"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=0, atol=1e-9)
        np.testing.assert_allclose(arm.tip_jacobian(psi), arm_tip_jacobian(spec, psi), rtol=0, atol=1e-9)
        a = arm_actuators(spec, psi)
        back = arm_psi_from_actuators(spec, a, psi)
        np.testing.assert_allclose(arm_actuators(spec, back), a, rtol=0, atol=1e-14)  # [m] or [rad]
        np.testing.assert_allclose(arm_frames(spec, back).T_world_tip, ref.T_world_tip, rtol=0, atol=1e-9)
