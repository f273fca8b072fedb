"""Nominal position IK: converges to 1e-7 m, stays within the joint limits, reports failure."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.models.errors import InputError
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import tip_position
from wristmark.models.limits import within_limits
from wristmark.models.robot_params import HOME_PSI, RobotParams

PARAMS = RobotParams()
HOME = np.array(HOME_PSI)
CENTRE = tip_position(PARAMS, HOME)


def test_random_workspace_targets_converge() -> None:
    rng = np.random.default_rng(0)
    for _ in range(40):
        target = CENTRE + rng.uniform(-1.0, 1.0, 3) * np.array([0.02, 0.02, 0.02])
        res = solve_tip_ik(PARAMS, target, HOME)
        assert res.converged
        assert res.error <= 1e-7
        assert np.linalg.norm(tip_position(PARAMS, res.psi) - target) <= 1e-7
        assert within_limits(PARAMS, res.psi)
        assert res.iterations <= 10


def test_nearby_start_converges_in_few_iterations() -> None:
    res = solve_tip_ik(PARAMS, CENTRE + np.array([0.001, -0.0005, 0.0005]), HOME)
    assert res.converged and res.iterations <= 4
    assert np.linalg.norm(res.psi - HOME) < 0.1  # minimum-norm steps stay near the start


def test_already_at_target() -> None:
    res = solve_tip_ik(PARAMS, CENTRE, HOME)
    assert res.iterations == 0 and res.converged
    np.testing.assert_allclose(res.psi, HOME)


def test_unreachable_target_reports_not_converged() -> None:
    res = solve_tip_ik(PARAMS, np.array([0.0, 0.0, 1.0]), HOME)  # 1 m away: beyond any reach
    assert not res.converged
    assert res.error > 0.5
    assert within_limits(PARAMS, res.psi)


@pytest.mark.parametrize("bad", [[0.0, 0.0], [0.0, np.nan, 0.1], "abc"])
def test_bad_target_raises(bad: object) -> None:
    with pytest.raises(InputError):
        solve_tip_ik(PARAMS, bad, HOME)


def test_bad_start_raises() -> None:
    with pytest.raises(InputError):
        solve_tip_ik(PARAMS, CENTRE, np.zeros(5))
