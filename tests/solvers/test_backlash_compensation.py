"""Dead-band inversion (solvers/backlash_compensation.py) and the tip-error integral
(solvers/tip_integral.py): unit behaviour, limits, and the closed loop on an unseen arm."""

import dataclasses

import numpy as np
import pytest

from tests import old_defaults
from wristmark.models.limits import psi_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers.backlash_compensation import BacklashInverse
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller
from wristmark.solvers.tip_integral import TipErrorIntegral

P = RobotParams()
PLAY = np.array([0.006, 8e-5, 8e-5, 8e-5, 7e-5, 7e-5])


def _play_operator(y: np.ndarray, motor: np.ndarray, play: np.ndarray) -> np.ndarray:
    return np.clip(y, motor - play / 2, motor + play / 2)


def test_inversion_flips_the_right_way_and_ignores_jitter() -> None:
    inv = BacklashInverse(PLAY, hysteresis=0.1, start=1.0, fraction=1.0, learn=False)
    a = np.zeros(6)
    assert np.all(inv.offset(a, 0.06) == 0)  # not moved yet: no direction, no offset
    for _ in range(3):
        a = a + 0.5 * PLAY
        off = inv.offset(a, 0.06)
    np.testing.assert_allclose(off, PLAY / 2)  # moving up: the motor leads by half the play
    jitter = a - 0.05 * PLAY  # back by less than the threshold (0.1 play_max): still up
    np.testing.assert_allclose(inv.offset(jitter, 0.06), PLAY / 2)
    back = a - 0.3 * PLAY  # back past the threshold: reversed, the offset flips
    np.testing.assert_allclose(inv.offset(back, 0.06), -PLAY / 2)


def test_inversion_cancels_a_play_operator() -> None:
    """Commands through a play: the arm follows the nominal command within a tenth of the play."""
    errs = {}
    for comp in (False, True):
        inv = BacklashInverse(PLAY, hysteresis=0.05, start=1.0, fraction=1.0, learn=False)
        y, e = np.zeros(6), []
        for k in range(300):
            a = 3 * PLAY * np.sin(2 * np.pi * k * 0.06 / 4.0 + np.arange(6))
            y = _play_operator(y, a + (inv.offset(a, 0.06) if comp else 0.0), PLAY)
            e.append(np.abs(y - a) / PLAY)
        errs[comp] = np.max(e[50:], axis=0)
    assert np.all(errs[False] > 0.45) and np.all(errs[True] < 0.1)


@pytest.mark.parametrize("share", [0.25, 0.5])
def test_play_learnt_in_a_loop_with_feedback(share: float) -> None:
    """An integrating loop through a play, triangle path: the learnt play is the true one plus the
    documented bias 2 x path rate x the loop's delay (here one step), and it tracks the true play."""
    true_play = share * PLAY
    inv = BacklashInverse(PLAY, hysteresis=0.1, start=0.1, fraction=0.75, learn=True)
    dt, y, a, r = 0.01, np.zeros(6), np.zeros(6), np.zeros(6)
    rate = 5 * PLAY  # [unit/s]
    for k in range(8000):
        v = rate * np.sign(np.sin(2 * np.pi * k * dt / 4.0 + 0.3))  # path rate, reverses every 2 s
        r = r + v * dt  # the desired actuator path
        a = a + (v + 15.0 * (r - y)) * dt  # feed-forward + integrating feedback on the arm's output
        y = _play_operator(y, a + inv.offset(a, dt, v), true_play)
    np.testing.assert_allclose(inv.play, true_play + 2 * rate * dt, rtol=0.1)


def test_integral_cancels_a_constant_velocity_disturbance() -> None:
    integ = TipErrorIntegral(ki=3.0, limit=0.003)
    p, dt, kp = np.zeros(3), 0.06, 8.0
    d = np.array([0.001, -0.0005, 0.0])  # [m/s] the arm drifts (e.g. a gain error at constant speed)
    for _ in range(400):
        e = -p
        p = p + (kp * e + integ.update(e, dt) + d) * dt
    assert np.linalg.norm(p) < 1e-6  # P alone would sit at |d| / kp = 0.14 mm
    np.testing.assert_allclose(integ.update(-p, dt), -d, atol=1e-6)
    big = TipErrorIntegral(ki=3.0, limit=0.003)
    for _ in range(200):
        v = big.update(np.array([0.05, 0, 0]), dt)
    assert np.linalg.norm(v) == pytest.approx(0.003)  # capped, and the state does not wind up
    assert np.linalg.norm(big.update(np.array([-0.001, 0, 0]), dt)) < 0.003


@pytest.mark.parametrize("kind", ["qp", "paper"])
def test_compensated_steps_stay_within_limits(kind: str) -> None:
    cfg = old_defaults.controller(kind=kind, backlash_compensation=True, ki=3.0)
    c = make_controller(P, cfg)
    rng = np.random.default_rng(3)
    psi = np.array(HOME_PSI, float)
    lo, hi = psi_bounds(P)
    from wristmark.models.kinematics import tip_position

    for k in range(200):
        p = tip_position(P, psi)
        p_des = p + rng.normal(0, 0.004, 3) * (1 if k % 20 < 10 else -1)
        step = c.step(psi, p, p_des, rng.normal(0, 0.01, 3), 0.06)
        assert np.all(np.abs(step.psi_dot) <= np.asarray(P.max_velocity) * (1 + 1e-9))
        assert np.all(step.psi_next >= lo - 1e-12) and np.all(step.psi_next <= hi + 1e-12)
        psi = step.psi_next
    assert c.compensator is not None and np.any(c.compensator.inverse.direction != 0)


def test_config_rejects_bad_backlash_keys() -> None:
    from wristmark.models.errors import ConfigError

    with pytest.raises(ConfigError, match="backlash_play_max"):
        ControllerConfig(backlash_play_max=(0.0, -1.0)).validate()
    with pytest.raises(ConfigError, match=r"'backlash_play_max' must have 6 entries \(one per actuator: phi, d, s1a"):
        ControllerConfig(backlash_play_max=(0.0, 1.0)).play_max_for(RobotParams())
    with pytest.raises(ConfigError, match="backlash_fraction"):
        ControllerConfig(backlash_fraction=1.5).validate()


CONTROLLER_FILES = ["controller_backlash.yaml", "controller_encoders.yaml"]  # Schmitt trigger; encoders


def _cube(plant: str, compensation: bool, duration: float, controller: str = "controller_backlash.yaml") -> dict:
    import tempfile
    from pathlib import Path

    from wristmark.sim.experiments import run_cube
    from wristmark.sim.setup import default_config, load_setup

    setup = load_setup(plant=default_config(plant), controller=default_config(controller))
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"),
                               controller=dataclasses.replace(setup.controller, backlash_compensation=compensation))
    with tempfile.TemporaryDirectory() as tmp:
        return run_cube(setup, Path(tmp), progress=False, duration=duration, seed=1)["closed_loop"]


@pytest.mark.slow
@pytest.mark.parametrize("controller", CONTROLLER_FILES)
def test_compensation_lowers_the_max_on_an_unseen_arm(controller: str) -> None:
    """Short cube (truth-noise sensor) on configs/plant_unseen.yaml with configs/controller_backlash.yaml
    (Schmitt trigger) or configs/controller_encoders.yaml (the encoders' play observer) and its
    inversion turned off and on: the inversion, learning the play online from its bound, cuts the
    closed-loop max, measured here both ways."""
    off, on = _cube("plant_unseen.yaml", False, 16.0, controller), _cube("plant_unseen.yaml", True, 16.0, controller)
    assert on["max_mm"] < 0.85 * off["max_mm"]
    assert on["mean_mm"] <= off["mean_mm"]


@pytest.mark.slow
@pytest.mark.parametrize("controller", CONTROLLER_FILES)
def test_compensation_does_not_hurt_the_default_arm(controller: str) -> None:
    """Same short cube on configs/plant.yaml: mean no worse, max within 5 % (noise)."""
    off, on = _cube("plant.yaml", False, 16.0, controller), _cube("plant.yaml", True, 16.0, controller)
    assert on["mean_mm"] <= off["mean_mm"]
    assert on["max_mm"] <= 1.05 * off["max_mm"]


def test_lead_bursts_at_a_flip_and_crosses_a_lagged_play_sooner() -> None:
    """The offset's lead: one cycle of (1 + lead/dt) x the jump at a reversal, then the steady
    offset; through a first-order motor lag (tau 70 ms) and a play the arm resumes following a
    reversed command sooner than without the lead."""
    dt, tau = 0.06, 0.07
    inv = BacklashInverse(PLAY, hysteresis=0.1, start=1.0, fraction=1.0, learn=False, lead=0.03)
    a = np.zeros(6)
    for _ in range(3):
        a = a + 0.5 * PLAY
        inv.offset(a, dt)
    np.testing.assert_allclose(inv.offset(a + 0.5 * PLAY, dt), PLAY / 2)  # steady: no burst
    a = a + 0.5 * PLAY - 0.3 * PLAY
    np.testing.assert_allclose(inv.offset(a, dt), -PLAY / 2 - 0.5 * PLAY)  # -b/2 + 0.03/0.06 x (-b)
    np.testing.assert_allclose(inv.offset(a - 0.2 * PLAY, dt), -PLAY / 2)  # settled
    assert np.all(inv.half >= PLAY / 2 * 2.0 - 1e-12)  # the bound on the offset covers the burst

    def excess_lag_after_reversal(lead: float) -> float:
        """Largest lag behind the reversed command beyond the motor's steady lag [x play]."""
        inv = BacklashInverse(PLAY, hysteresis=0.1, start=1.0, fraction=1.0, learn=False, lead=lead)
        y, m, err = np.zeros(6), np.zeros(6), []
        alpha = 1.0 - np.exp(-dt / tau)
        for k in range(60):
            a = 4 * PLAY * (k if k < 30 else 60 - k) / 30.0  # up for 30 cycles, then back down
            m = m + alpha * (a + inv.offset(a, dt) - m)
            y = _play_operator(y, m, PLAY)
            err.append(np.max(np.abs(y - a) / PLAY))
        return max(err[30:45]) - err[25]

    without = excess_lag_after_reversal(0.0)
    assert without > 0.05 and excess_lag_after_reversal(0.03) < 0.5 * without


def test_config_rejects_a_negative_lead() -> None:
    from wristmark.models.errors import ConfigError

    with pytest.raises(ConfigError, match="backlash_lead"):
        ControllerConfig(backlash_lead=-0.01).validate()


def test_play_max_is_sized_to_any_arm() -> None:
    """The reference arm's six entries are sized to another arm by actuator kind; a list of the
    arm's own length is taken as it is; any other length is refused naming the actuators."""
    from wristmark.models.arm_spec import load_arm
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.models.errors import ConfigError

    arm = load_arm(CONFIG_DIR / "robots" / "tendon3.yaml")  # d, then nine tendons
    cfg = ControllerConfig(backlash_play_max=(0.012, 0.0002, 0.00016, 0.00016, 0.00016, 0.00017))
    np.testing.assert_array_equal(cfg.play_max_for(arm), [0.0002] + [0.00017] * 9)
    own = tuple(float(i) for i in range(arm.m))
    np.testing.assert_array_equal(ControllerConfig(backlash_play_max=own).play_max_for(arm), own)
    with pytest.raises(ConfigError, match=r"must have 10 entries \(one per actuator: d, s1a, s1b"):
        ControllerConfig(backlash_play_max=(0.1, 0.1)).play_max_for(arm)


def _tendon3_walk(inverse: BacklashInverse | None, play: np.ndarray) -> float:
    """tendon3 (10 actuators, 7 joints) through a known per-actuator play (the simulated true arm,
    no other error), its configuration walked along a smooth loop that reverses every tendon: the
    largest tip error [m] after the first reversals, commanded through the actuator-space inversion
    (its targets = the nominal actuators + the offsets) or without one (None)."""
    from wristmark.models.actuation import actuator_jacobian, actuators_from_psi
    from wristmark.models.arm_spec import home_psi, load_arm
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.models.kinematics import tip_position
    from wristmark.sim.plant import TruePlant
    from wristmark.sim.plant_params import PlantParams
    from wristmark.solvers.backlash_compensation import ActuatorCompensator

    arm = load_arm(CONFIG_DIR / "robots" / "tendon3.yaml")
    psi0 = home_psi(arm)
    plant = TruePlant(arm, PlantParams(bend_gain=(1.0,) * 3, plane_offset=(0.0,) * 3, backlash=tuple(play),
                                       segment_stiffness=(1.0,) * 3), psi0=psi0)
    comp = None if inverse is None else ActuatorCompensator(arm, inverse)
    dt, errs = 0.06, []
    amp = np.array([0.004, 0.08, 0.5, 0.08, 0.5, 0.08, 0.5])  # [m, rad, rad, ...]
    psi_cmd = psi0
    for k in range(200):
        w = 2 * np.pi * k * dt / 4.0
        psi_nom = psi0 + amp * np.sin(w + np.arange(7))
        rate = amp * np.cos(w + np.arange(7)) * 2 * np.pi / 4.0
        if comp is None:
            target = actuators_from_psi(arm, psi_nom)
        else:
            psi_cmd = comp.nominal(psi_cmd)  # the loop hands back the last command
            out = comp.compensate(psi_nom, dt, rate)
            np.testing.assert_allclose(out, psi_nom)  # the configuration stays the nominal one
            comp.commit(psi_nom, out)
            psi_cmd = out
            target = comp.actuators(out)
            assert np.all(np.abs(target - actuators_from_psi(arm, out)) <= comp.inverse.half + 1e-15)
            assert actuator_jacobian(arm, out).shape == (10, 7)
        plant.command(target)
        plant.advance(dt)
        if k >= 50:
            errs.append(np.linalg.norm(plant.true_tip() - tip_position(arm, psi_nom)))
    return float(max(errs))


def test_actuator_space_inversion_removes_a_known_tendon_play() -> None:
    """The dead-band inversion in actuator space (ActuatorCompensator) on a tendon arm with more
    actuators than joints: a play of 60 um in every tendon (and the feed) costs the open command
    a large tip error; with the play known and inverted per actuator the error is a small share."""
    play = np.array([1e-4] + [6e-5] * 9)
    without = _tendon3_walk(None, play)
    inv = BacklashInverse(play, hysteresis=0.05, start=1.0, fraction=1.0, learn=False)
    with_inv = _tendon3_walk(inv, play)
    assert without > 5e-4  # the play alone: over half a millimetre at the tip
    assert with_inv < 0.1 * without


def test_tendon_arm_gets_the_actuator_space_inversion_and_can_turn_it_off() -> None:
    """An arm with more actuators than joints: the controller keeps the nominal configuration
    and adds the offsets to the actuator targets it hands the loop (their note says so); with
    backlash_actuator_space off it has no inversion, and the paper arm (6 = 6) keeps the
    configuration-space one."""
    from wristmark.models.actuation import actuators_from_psi
    from wristmark.models.arm_spec import home_psi, load_arm
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.models.kinematics import tip_position
    from wristmark.solvers.backlash_compensation import ActuatorCompensator, CommandCompensator

    arm = load_arm(CONFIG_DIR / "robots" / "single_tendon.yaml")
    cfg = ControllerConfig(backlash_method="schmitt", backlash_motor_burst=False, backlash_start=1.0,
                           backlash_lead=0.0, play_probe=False)
    ctrl = make_controller(arm, cfg)
    assert isinstance(ctrl.compensator, ActuatorCompensator)
    assert "actuator space" in ctrl.compensation_note
    psi = home_psi(arm)
    p0 = tip_position(arm, psi)
    offsets = []
    for k in range(1, 8):  # the tip pulled along +x: the command moves one way
        step = ctrl.step(psi, p0, p0 + np.array([0.0005 * k, 0.0, 0.0]), None, 0.06)
        psi = step.psi_next
        np.testing.assert_allclose(ctrl.output_model(psi), psi)  # the configuration is the nominal one
        offsets.append(ctrl.actuator_targets(psi) - actuators_from_psi(arm, psi))
    assert np.max(np.abs(offsets[-1])) > 0.0
    assert np.all(np.abs(offsets[-1]) <= ctrl.compensator.inverse.half + 1e-15)
    np.testing.assert_array_equal(ctrl.actuator_targets(psi + 0.01), actuators_from_psi(arm, psi + 0.01))  # not ours
    off = make_controller(arm, dataclasses.replace(cfg, backlash_actuator_space=False))
    assert off.compensator is None and "off" in off.compensation_note
    assert isinstance(make_controller(P, cfg).compensator, CommandCompensator)
