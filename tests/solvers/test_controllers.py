"""Controllers: the paper's eq. 17-21, the CasADi QP, limits, convergence, configuration."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

from tests import old_defaults
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import tip_jacobian, tip_position
from wristmark.models.limits import psi_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller
from wristmark.solvers.pseudo_inverse import sr_pseudo_inverse
from wristmark.solvers.qp_controller import BoxQp

P = RobotParams()
HOME = np.array(HOME_PSI)
CONFIGS = CONFIG_DIR


def test_default_file_loads() -> None:
    cfg = ControllerConfig.load(CONFIGS / "controller.yaml")
    assert cfg.kind in ("paper", "qp") and cfg.dt == pytest.approx(0.060)


def test_unknown_kind_lists_valid_ones() -> None:
    with pytest.raises(ConfigError, match="valid kinds: paper, qp"):
        make_controller(P, ControllerConfig(kind="pid"))


@pytest.mark.parametrize("text, key", [("controller:\n  kp: -1\n", "kp"), ("controller:\n  dt: 0\n", "dt"),
                                       ("controller:\n  foo: 1\n", "foo"),
                                       ("controller:\n  qp_solver: osqp\n", "qp_solver")])
def test_config_errors_name_key_and_file(tmp_path: Path, text: str, key: str) -> None:
    f = tmp_path / "c.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        ControllerConfig.load(f)
    assert key in str(e.value) and str(f) in str(e.value)


def test_paper_step_matches_eq_18_to_21_by_hand() -> None:
    cfg = old_defaults.controller(kind="paper", v_xlim=0.01, gamma=1e-6, xi=1e-3)
    c = make_controller(P, cfg)
    dt = 0.06
    p_c = tip_position(P, HOME)
    p_d = p_c + np.array([0.003, -0.001, 0.002])
    dp = p_d - p_c  # eq. 17
    v = 0.01 * dp / np.linalg.norm(dp)  # eq. 18
    J = tip_jacobian(P, HOME)
    s = np.linalg.svd(J, compute_uv=False)
    Jp = J.T @ np.linalg.inv(J @ J.T + 1e-6 * np.eye(6)) if s[-1] < 1e-3 else np.linalg.pinv(J)  # eq. 20
    psi_dot = Jp @ np.r_[v, 0, 0, 0]  # eq. 19
    step = c.step(HOME, p_c, p_d, None, dt)
    np.testing.assert_allclose(step.psi_next, HOME + psi_dot * dt, atol=1e-12)  # eq. 21
    np.testing.assert_allclose(step.v_tip_cmd, v, atol=1e-15)


def test_sr_pseudo_inverse_damps_only_near_singular() -> None:
    J = np.diag([1.0, 1.0, 1e-5])
    assert np.allclose(sr_pseudo_inverse(np.eye(3), 1e-2, 1e-3), np.eye(3))
    damped = sr_pseudo_inverse(J, 1e-4, 1e-3)
    assert damped[2, 2] == pytest.approx(1e-5 / (1e-10 + 1e-4))


@pytest.mark.parametrize("kind", ["paper", "qp"])
def test_error_decreases_on_a_static_target(kind: str) -> None:
    c = make_controller(P, old_defaults.controller(kind=kind, saturate_near_target=True))
    q = HOME.copy()
    target = tip_position(P, q) + np.array([0.004, 0.003, -0.005])
    errs = [np.linalg.norm(tip_position(P, q) - target)]
    for _ in range(25):
        q = c.step(q, tip_position(P, q), target, np.zeros(3), 0.06).psi_next
        errs.append(np.linalg.norm(tip_position(P, q) - target))
    big = [e for e in errs if e > 2e-4]
    assert all(b < a for a, b in zip(big, big[1:])), errs
    assert errs[-1] < 1e-4


def test_paper_locks_a_joint_at_its_limit_and_moves_the_others() -> None:
    """At the stem feed's lower end stop, a target that eq. 19 would reach by retracting the stem:
    with locking, d stays at its stop, the other joints follow J^+ with d's column removed and the
    tip moves along v; without locking, the clipped step loses that part of the motion."""
    q = HOME.copy()
    q[1] = P.d_range[0]  # d at its lower stop
    J = tip_jacobian(P, q)
    dp = -0.003 * J[:3, 1] / np.linalg.norm(J[:3, 1])  # straight back along the stem
    p_c = tip_position(P, q)
    locked = make_controller(P, old_defaults.controller(kind="paper", v_xlim=0.01))
    clipped = make_controller(P, old_defaults.controller(kind="paper", v_xlim=0.01, lock_saturated_joints=False))
    dt = 0.06
    a, b = locked.step(q, p_c, p_c + dp, None, dt), clipped.step(q, p_c, p_c + dp, None, dt)
    assert a.psi_next[1] == P.d_range[0] and b.psi_next[1] == P.d_range[0]
    free = np.ones(6)
    free[1] = 0.0
    expected = sr_pseudo_inverse(J * free, 1e-6, 1e-3) @ np.r_[a.v_tip_cmd, 0, 0, 0]
    np.testing.assert_allclose(a.psi_dot, expected, atol=1e-12)
    # the clipped step leaves the tip where it was (all of v was d's); the locked one gets closer
    # (not by the full v dt: eq. 19 also asks the tip frame not to rotate, which 5 joints cannot
    # quite do while translating along the stem)
    err_locked = np.linalg.norm(tip_position(P, a.psi_next) - (p_c + dp))
    err_clipped = np.linalg.norm(tip_position(P, b.psi_next) - (p_c + dp))
    assert err_clipped == pytest.approx(np.linalg.norm(dp), abs=1e-9)
    assert err_locked < err_clipped - 1e-4


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.sampled_from(["paper", "qp"]), st.lists(st.floats(-1, 1), min_size=6, max_size=6),
       st.lists(st.floats(-0.05, 0.05), min_size=3, max_size=3), st.floats(0.005, 0.2))
def test_limits_never_exceeded(kind: str, u: list[float], dp: list[float], dt: float) -> None:
    lo, hi = psi_bounds(P)
    span_lo = np.where(np.isfinite(lo), lo, -np.pi)
    span_hi = np.where(np.isfinite(hi), hi, np.pi)
    q = span_lo + (np.asarray(u) + 1) / 2 * (span_hi - span_lo)
    c = make_controller(P, old_defaults.controller(kind=kind, v_xlim=0.05, kp=50.0, max_correction_speed=0.2))
    step = c.step(q, tip_position(P, q), tip_position(P, q) + np.asarray(dp), np.asarray(dp), dt)
    assert np.all(step.psi_next >= lo - 1e-12) and np.all(step.psi_next <= hi + 1e-12)
    assert np.all(np.abs(step.psi_dot) <= np.asarray(P.max_velocity) + 1e-9)


def test_box_qp_matches_bounded_least_squares() -> None:
    qp = BoxQp("daqp")
    rng = np.random.default_rng(3)
    for _ in range(50):
        A = rng.normal(size=(9, 6))
        b = rng.normal(size=9)
        lo, hi = -rng.uniform(0.05, 1, 6), rng.uniform(0.05, 1, 6)
        x = qp.solve(2 * A.T @ A, -2 * A.T @ b, lo, hi)
        ref = lsq_linear(A, b, bounds=(lo, hi), tol=1e-12).x
        np.testing.assert_allclose(x, ref, atol=1e-7)


@pytest.mark.parametrize("robot", ["tendon3.yaml", "single_tendon.yaml", "planar.yaml"])
def test_undamped_feed_forward_realises_the_path_velocity(robot: str) -> None:
    """The QP's damping shortens the tip velocity it asks for (near home: by percents); with
    feed_forward_undamped the damping pulls towards the rates that realise the desired velocity,
    so at zero error the tip velocity is the desired one where nothing else competes (an arm of
    fewer than 6 joints; tendon3, n = 7, also keeps its tip frame's orientation: exact once that
    weight is 0, docs/notes/any-arm-residual.md)."""
    import dataclasses

    from wristmark.models.arm_spec import home_psi, load_arm

    arm = load_arm(CONFIG_DIR / "robots" / robot)
    psi = home_psi(arm)
    p = tip_position(arm, psi)
    v = np.array([0.006, -0.004, 0.007])  # [m/s]
    cfg = dataclasses.replace(ControllerConfig(), backlash_compensation=False, ki=0.0)
    if arm.n > 6:
        cfg = dataclasses.replace(cfg, orientation_weight=0.0)
    realised = {}
    for undamped in (False, True):
        ctrl = make_controller(arm, dataclasses.replace(cfg, feed_forward_undamped=undamped))
        psi_dot, _, status = ctrl.velocity(psi, p, p, v, 0.06)
        assert status == "ok"
        realised[undamped] = tip_jacobian(arm, psi)[:3] @ psi_dot
    assert np.linalg.norm(realised[False] - v) > 0.005 * np.linalg.norm(v)
    np.testing.assert_allclose(realised[True], v, atol=1e-3 * np.linalg.norm(v))
