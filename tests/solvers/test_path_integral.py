"""The tip-error integral scheduled on the desired path's velocity (solvers/tip_integral.py,
``integral_mode: path``): what it learns along one direction does not wind up another, and on a
gain-mismatched arm it keeps the track close to the matched arm's at the corners."""

import numpy as np
import pytest

from tests import old_defaults
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import tip_position
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller
from wristmark.solvers.tip_integral import TipErrorIntegral

DT = 0.06
# an arm whose tip moves by M x the commanded tip velocity (gain errors and a cross-coupling)
M = np.array([[1.1, 0.05, 0.0], [-0.04, 0.85, 0.0], [0.0, 0.03, 1.0]])


def test_a_direction_learnt_does_not_wind_up_a_new_one() -> None:
    plain, path = TipErrorIntegral(4.0, 0.003), TipErrorIntegral(4.0, 0.003)
    v_y = np.array([0.0, 0.01, 0.0])
    e = np.array([0.0, 2e-4, 0.0])  # [m] the arm lags along +y
    for _ in range(20):
        plain.update(e, DT)
        out = path.update_path(e, v_y, DT)
    np.testing.assert_allclose(out, plain.update(np.zeros(3), DT), rtol=1e-9)  # along the path: the same
    assert out[1] > 1e-4
    zero = np.zeros(3)
    # the path turns to -x: the plain integral still pushes along +y, the path one does not
    assert plain.update(zero, DT)[1] == pytest.approx(out[1])
    np.testing.assert_allclose(path.update_path(zero, np.array([-0.01, 0.0, 0.0]), DT), 0.0, atol=1e-12)
    # the path reverses to -y: a gain error reverses with the motion
    np.testing.assert_allclose(path.update_path(zero, -v_y, DT), -out, rtol=1e-9)
    # a path that stands still: no term, nothing learnt
    np.testing.assert_allclose(path.update_path(e, zero, DT), 0.0)
    np.testing.assert_allclose(path.update_path(e, None, DT), 0.0)


def test_path_integral_is_capped() -> None:
    path = TipErrorIntegral(4.0, 0.003)
    v = np.array([0.01, 0.0, 0.0])
    for _ in range(400):
        out = path.update_path(np.array([0.05, 0.0, 0.0]), v, DT)
    assert np.linalg.norm(out) == pytest.approx(0.003)
    assert np.linalg.norm(path.update_path(np.array([-0.001, 0.0, 0.0]), v, DT)) < 0.003  # no wind-up


def _square(mode: str, arm: np.ndarray, laps: int = 3, kp: float = 8.0, ki: float = 4.0) -> tuple[np.ndarray, int]:
    """A 20 mm square at 10 mm/s, the tip measured one cycle late; tip positions [m], cycles a lap."""
    pts = np.array([[0, 0, 0], [0.02, 0, 0], [0.02, 0.02, 0], [0, 0.02, 0], [0, 0, 0]], float)
    T = np.arange(5) * 2.0

    def des(t: float) -> tuple[np.ndarray, np.ndarray]:
        t = t % T[-1]
        k = min(int(t // 2.0), 3)
        u = (pts[k + 1] - pts[k]) / 0.02
        return pts[k] + u * 0.01 * (t - T[k]), u * 0.01

    integ = TipErrorIntegral(ki, 0.003)
    p, seen, out = np.zeros(3), np.zeros(3), []
    for k in range(int(laps * T[-1] / DT)):
        pd, vd = des(k * DT)
        e = pd - seen
        vi = integ.update_path(e, vd, DT) if mode == "path" else integ.update(e, DT)
        seen = p.copy()
        p = p + arm @ (vd + np.clip(kp * e, -0.02, 0.02) + vi) * DT
        out.append(p.copy())
    return np.array(out), int(T[-1] / DT)


def test_on_a_mismatched_arm_the_corners_stay_near_the_matched_track() -> None:
    ideal, lap = _square("plain", np.eye(3))
    dev = {m: np.linalg.norm(_square(m, M)[0] - ideal, axis=1)[lap:] for m in ("plain", "path")}
    assert dev["path"].max() < 0.6 * dev["plain"].max()  # measured 0.25 against 0.56 mm
    assert dev["path"].mean() < 0.5 * dev["plain"].mean()  # 0.05 against 0.17 mm


def test_config_selects_and_validates_the_mode() -> None:
    with pytest.raises(ConfigError, match="integral_mode"):
        ControllerConfig(integral_mode="direction").validate()
    P = RobotParams()
    p0 = tip_position(P, np.asarray(HOME_PSI))
    v = np.array([0.0, 0.01, 0.0])
    steps = {}
    for mode in ("plain", "path"):
        c = make_controller(P, old_defaults.controller(kind="qp", ki=4.0, integral_mode=mode))
        c.reset()
        for _ in range(10):
            c.reference_velocity(p0 + np.array([0, 1e-4, 0]), p0 + np.array([0, 2e-4, 0]), v, DT)
        steps[mode] = c.reference_velocity(p0, p0, np.array([-0.01, 0.0, 0.0]), DT)
    # after a turn to -x the plain integral still adds its +y term; the path mode adds none along y
    assert steps["plain"][1] > 1e-5
    assert abs(steps["path"][1]) < 1e-12
