"""The encoders' dead-band inversion (solvers/play_observer.py): the observed play output, the
inverse through a lagged play, learning, rounding, and the closed loop on an unseen arm."""

import dataclasses

import numpy as np
import pytest

from tests import old_defaults
from wristmark.models.errors import ConfigError
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller
from wristmark.solvers.play_observer import PlayObserverInverse

P = RobotParams()
PLAY = np.array([0.006, 8e-5, 8e-5, 8e-5, 7e-5, 7e-5])
DT, TAU = 0.06, 0.07  # the loop's cycle, the motor's lag [s]


def _play_operator(y: np.ndarray, motor: np.ndarray, play: np.ndarray) -> np.ndarray:
    return np.clip(y, motor - play / 2, motor + play / 2)


def _known(play: np.ndarray = PLAY, **kw: float) -> PlayObserverInverse:
    """An inversion given the true play (no learning)."""
    args = dict(start=1.0, fraction=1.0, learn=False, lead=0.0) | kw
    return PlayObserverInverse(play, 0.01, **args)  # type: ignore[arg-type]


def test_observer_tracks_the_play_output_from_the_encoders() -> None:
    """Motor readings through a play: once the motor has touched an edge of the band, the
    observed output is the true one to within the micro-unit rounding."""
    inv = _known()
    y = np.zeros(6) + 0.3 * PLAY  # the output sits off the middle of the band at the start
    for k in range(200):
        m = 2 * PLAY * np.sin(2 * np.pi * k * DT / 3.0 + np.arange(6))
        y = _play_operator(y, m, PLAY)
        inv.observe(m)
        if k > 60:
            assert inv.output is not None
            np.testing.assert_allclose(inv.output, y, rtol=0, atol=1.01e-6)


def _through_lagged_play(inv: PlayObserverInverse | None, n: int = 300,
                         jitter: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A slow sine command through a first-order motor and a play; returns the arm's output and
    the nominal command, per cycle."""
    alpha = 1.0 - np.exp(-DT / TAU)
    y, m, ys, us = np.zeros(6), np.zeros(6), [], []
    for k in range(n):
        u = 3 * PLAY * np.sin(2 * np.pi * k * DT / 6.0 + np.arange(6))
        if jitter is not None:
            u = u + jitter[k]
        target = u
        if inv is not None:
            inv.observe(m)
            target = u + inv.offset(u, DT)
        for _ in range(60):  # 1 ms steps within the cycle
            m = m + (1.0 - (1.0 - alpha) ** (1 / 60)) * (target - m)
            y = _play_operator(y, m, PLAY)
        ys.append(y.copy())
        us.append(u)
    return np.array(ys), np.array(us)


def test_inverse_cancels_a_lagged_play() -> None:
    """The arm's output follows the nominal command (one cycle behind, the motor's lag) much closer
    with the inversion than without: the play's half-width lag goes away."""
    errs = {}
    for name, inv in (("off", None), ("on", _known(lead=0.03))):
        y, u = _through_lagged_play(inv)
        errs[name] = np.max(np.abs(y[100:] - u[99:-1]) / PLAY, axis=0)
    assert np.all(errs["off"] > 0.45)
    assert np.all(errs["on"] < 0.5 * errs["off"])


def test_one_micrometre_of_rounding_moves_the_output_by_no_more_than_it() -> None:
    """The same commands, rounded to micro-units or with +-1 um of jitter: a change of side a
    cycle early or late moves the motor inside the band, so the output moves by no more than
    the command's own change (far less than the play: the Schmitt trigger's failure)."""
    rng = np.random.default_rng(0)
    base, _ = _through_lagged_play(_known(fraction=0.75, lead=0.03))
    jittered, _ = _through_lagged_play(_known(fraction=0.75, lead=0.03), jitter=rng.uniform(-1e-6, 1e-6, (300, 6)))
    assert np.max(np.abs(jittered - base)[:, 1:]) < 5e-6  # the backbones [m]; the play is 70-80 um


@pytest.mark.parametrize("share", [0.25, 0.5])
def test_play_learnt_from_the_encoders_loop(share: float) -> None:
    """An integrating loop (feedback on the arm's output) through a play, a triangle path: the
    learnt play starts at 0.1 x the bound and ends within 10 % of the true play plus the
    documented bias 2 x path rate x the loop's delay (one step)."""
    true_play = share * PLAY
    inv = PlayObserverInverse(PLAY, 0.01, start=0.1, fraction=0.75, learn=True)
    dt, y, a, r, m = 0.01, np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
    rate = 5 * PLAY  # [unit/s]
    for k in range(8000):
        v = rate * np.sign(np.sin(2 * np.pi * k * dt / 4.0 + 0.3))  # reverses every 2 s
        r = r + v * dt
        a = a + (v + 15.0 * (r - y)) * dt
        inv.observe(m)  # no motor lag here: the encoders read the last command
        m = a + inv.offset(a, dt, v)
        y = _play_operator(y, m, true_play)
    np.testing.assert_allclose(inv.play, true_play + 2 * rate * dt, rtol=0.1)


def test_controller_without_encoders_is_the_plain_controller() -> None:
    """A controller with the encoders' inversion on stepped without readings (the paper's
    interface, unit tests) inverts nothing; with readings it does."""
    cfg = old_defaults.controller(backlash_compensation=True, backlash_method="encoders", backlash_start=1.0)
    plain = make_controller(P, dataclasses.replace(cfg, backlash_compensation=False))
    comp = make_controller(P, cfg)
    assert comp.uses_encoders and not plain.uses_encoders
    psi = np.asarray(HOME_PSI, float)
    p_des = np.array([0.002, 0.0, 0.0])
    a, b = psi.copy(), psi.copy()
    from wristmark.models.actuation import actuators_from_psi
    from wristmark.models.kinematics import tip_position

    for _ in range(5):
        p = tip_position(P, a)
        a = plain.step(a, p, p + p_des, None, 0.06).psi_next
        b = comp.step(b, p, p + p_des, None, 0.06).psi_next
    np.testing.assert_allclose(a, b, atol=1e-12)
    c = comp.step(b, tip_position(P, b), tip_position(P, b) + p_des, None, 0.06,
                  encoders=actuators_from_psi(P, b)).psi_next
    c2 = comp.step(c, tip_position(P, c), tip_position(P, c) + p_des, None, 0.06,
                   encoders=actuators_from_psi(P, c)).psi_next
    d = plain.step(c, tip_position(P, c), tip_position(P, c) + p_des, None, 0.06).psi_next
    assert np.max(np.abs(actuators_from_psi(P, c2) - actuators_from_psi(P, d))) > 1e-5


def test_config_rejects_bad_method_and_margin() -> None:
    with pytest.raises(ConfigError, match="backlash_method"):
        ControllerConfig(backlash_method="guess").validate()
    with pytest.raises(ConfigError, match="backlash_margin"):
        ControllerConfig(backlash_margin=-0.1).validate()


def test_encoders_file_applies_to_the_qp_only() -> None:
    """configs/controller_encoders.yaml turns the encoders' inversion on for the qp kind; the paper
    kind runs without it (backlash_kinds), and an unknown kind in that list is refused."""
    from wristmark.sim.setup import default_config

    cfg = ControllerConfig.load(default_config("controller_encoders.yaml"))
    assert cfg.backlash_compensation and cfg.backlash_method == "encoders"
    assert make_controller(P, cfg).uses_encoders
    paper = make_controller(P, dataclasses.replace(cfg, kind="paper"))
    assert paper.compensator is None and not paper.uses_encoders
    with pytest.raises(ConfigError, match="backlash_kinds"):
        dataclasses.replace(cfg, backlash_kinds=("pid",)).validate()


def _first_reversal(inv: PlayObserverInverse, steps: int = 260) -> None:
    """test_play_learnt_from_the_encoders_loop's loop up to just after its first reversal's verdict."""
    dt, y, a, r, m = 0.01, np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
    rate = 5 * PLAY
    for k in range(steps):
        v = rate * np.sign(np.sin(2 * np.pi * k * dt / 4.0 + 0.3))
        r = r + v * dt
        a = a + (v + 15.0 * (r - y)) * dt
        inv.observe(m)
        m = a + inv.offset(a, dt, v)
        y = _play_operator(y, m, 0.5 * PLAY)


def test_a_start_move_makes_the_first_reversal_learnt_at_the_normal_rate() -> None:
    """Actuators the start ramp moved further than their play estimate learn their first reversal
    at ``rate`` (0.3 of the way from the start); the others replace the start with it."""
    plain = PlayObserverInverse(PLAY, 0.01, start=0.1, fraction=0.75, learn=True)
    moved = PlayObserverInverse(PLAY, 0.01, start=0.1, fraction=0.75, learn=True)
    before = np.array([0.1, 0.02, 0.0, 0.0, 0.0, 0.0])
    after = before + np.array([0.01, 1e-3, 1e-4, 1e-6, -1e-3, 0.0])  # moved: 0, 1, 2, 4 (> 0.1 x PLAY)
    moved.after_move(before, after)
    _first_reversal(plain)
    _first_reversal(moved)
    start = 0.1 * PLAY
    assert np.all(np.abs(plain.play - start) > 0.3 * start)  # the first verdict was given
    step_plain, step_moved = plain.play - start, moved.play - start
    was_moved = np.array([True, True, True, False, True, False])
    np.testing.assert_allclose(step_moved[was_moved], 0.3 * step_plain[was_moved], rtol=1e-9)
    np.testing.assert_array_equal(moved.play[~was_moved], plain.play[~was_moved])


def test_the_loop_tells_the_controller_where_its_start_ramp_left_the_play() -> None:
    """ServoLoop.start_at on an arm resting at home: the actuators its ramp moved are marked; an
    arm already at the start gets no ramp and nothing is marked."""
    from wristmark.models.config_files import default_config
    from wristmark.models.ik import solve_tip_ik
    from wristmark.models.kinematics import tip_position
    from wristmark.rig.link.actuator_link import DirectLink
    from wristmark.rig.loop.servo_loop import ServoLoop
    from wristmark.sim.plant import TruePlant
    from wristmark.sim.plant_params import PlantParams

    home = np.array(HOME_PSI, float)
    start = solve_tip_ik(P, tip_position(P, home) + [0.01, -0.005, 0.008], home).psi
    learnt = {}
    for name, rest in (("home", home), ("start", start)):
        ctrl = make_controller(P, ControllerConfig.load(default_config("controller.yaml")))
        assert ctrl.uses_encoders and ctrl.compensator is not None
        loop = ServoLoop(P, old_defaults.rig(sensor="truth-noise"), DirectLink(TruePlant(P, PlantParams(), psi0=rest)),
                         controller=ctrl)
        loop.start_at(start)
        learnt[name] = ctrl.compensator.inverse._learnt.copy()  # type: ignore[attr-defined]
    assert learnt["home"][0] > 0 and np.count_nonzero(learnt["home"]) >= 3
    assert not np.any(learnt["start"])



def _play_after_a_swinging_command(buzz_time: float, path_rate: float = 0.0, period: int = 1,
                                   start: float = 0.5, n: int = 20) -> tuple[float, int]:
    """Actuator 1's play estimate (a probe's, 87 um) and the shrinking turns after ``n`` cycles of
    its command swinging 5 um either side of its play's output every ``period`` cycles (the
    feedback alone, the motor standing; actuator 0 walks: the path is not held)."""
    inv = PlayObserverInverse(np.array([0.012, 1.6e-4]), 0.01, start=start, fraction=0.75, freeze=0.5,
                              buzz_time=buzz_time, buzz_shrink=0.7, buzz_turns=3)
    inv.seed(np.array([0.006, 8.7e-5]), np.zeros(2), np.array([True, True]), relearn=False)
    inv.observe(np.zeros(2))
    for k in range(n):
        u = np.array([0.001 * k, 5e-6 * (-1) ** (k // period)])
        inv.offset(u, DT, np.array([0.001 / DT, path_rate]))
        inv.observe(np.array([0.001 * k, 0.0]))
    return float(inv.play[1]), inv.buzzes


def test_an_actuator_the_feedback_alone_turns_back_and_forth_has_its_play_shrunk() -> None:
    """Each turn moves the motor by the inverted play: too large a play (a probe's under a loaded
    host, kept as measured) makes the feedback turn a standing actuator back and forth, the tip
    swinging (the scene lab's arm a, 0.4-0.8 mm). The third turn within ``buzz_time`` (1 s, 16.7
    cycles) made by the feedback alone, and each one after, shrinks that play by 0.7, a probe's
    too, not under ``start`` x the bound; turns the path asks for, or further apart, do not."""
    play, buzzes = _play_after_a_swinging_command(1.0, start=0.15)  # a turn every cycle: 19 turns
    assert buzzes == 17 and play == pytest.approx(0.15 * 1.6e-4)  # from the third on; down to the floor
    play, buzzes = _play_after_a_swinging_command(1.0, period=4, n=40)  # every 0.24 s: 4 turns a second
    assert buzzes == 7 and play == pytest.approx(0.5 * 1.6e-4)  # floor 80 um (start 0.5)
    assert _play_after_a_swinging_command(1.0, period=10, n=60)[1] == 0  # every 0.6 s: 2 turns a second
    assert _play_after_a_swinging_command(0.0) == (8.7e-5, 0)  # buzz_time 0: never
    # the path moves up: the turns up are asked for; each turn down, the feedback's, shrinks
    assert _play_after_a_swinging_command(1.0, path_rate=2e-5)[1] == 9


@pytest.mark.parametrize(("key", "value", "why"), [
    ("backlash_buzz_time", -1.0, ">= 0"), ("backlash_buzz_shrink", 1.5, "in \\[0, 1\\]"),
    ("backlash_buzz_turns", 0, "integer >= 1"), ("backlash_buzz_turns", 2.5, "integer >= 1")])
def test_the_buzz_settings_are_validated(key: str, value: float, why: str) -> None:
    with pytest.raises(ConfigError, match=f"'{key}' must be .*{why[:6]}"):
        dataclasses.replace(ControllerConfig(), **{key: value}).validate()


def _outputs_after_a_frozen_winding(release: float) -> tuple[np.ndarray, np.ndarray]:
    """One actuator of 30 um play (known, no learning, no motor lag): the path walks it down
    (side -), then stands 1.8 s, the sides frozen after 0.5 s, while the feedback winds the
    nominal command 24 um up inside the band, then walks it up. Returns the arm's output and the
    nominal command per cycle [m]."""
    inv = PlayObserverInverse(np.array([1.6e-4]), 0.01, start=3e-5 / 1.6e-4, fraction=0.75, learn=False,
                              freeze=0.5, release=release)
    a, y, m, ys, us = 0.0, np.zeros(1), np.zeros(1), [], []
    for k in range(70):
        rate = -2e-5 / DT if k < 10 else (0.0 if k < 40 else 1e-6 / DT)
        a += rate * DT + (2e-6 if 20 <= k < 32 else 0.0)
        inv.observe(m)
        m = a + inv.offset(np.array([a]), DT, np.array([rate]))
        y = _play_operator(y, m, np.array([3e-5]))
        ys.append(float(y[0]))
        us.append(a)
    return np.array(ys), np.array(us)


def test_a_winding_held_by_a_freeze_is_let_out_over_the_release_time() -> None:
    """A standing path freezes the sides: the feedback's winding against the side stays inside
    the band and the output stands. When the path moves again, released at once the first change
    of side lets the output jump by the winding (the tip kicked at a walk's first cycles); with
    ``release`` it is let out over that time constant, and the output ends on the command alike."""
    at_once, u = _outputs_after_a_frozen_winding(0.0)
    gradual, _ = _outputs_after_a_frozen_winding(0.4)
    np.testing.assert_array_equal(at_once[:40], gradual[:40])  # the same until the path moves
    assert np.ptp(at_once[19:40]) < 1e-9  # the winding moved no output while frozen
    jump_at_once, jump_gradual = np.max(np.diff(at_once[39:50])), np.max(np.diff(gradual[39:50]))
    assert jump_at_once > 1.5e-5  # most of the 24 um at once
    assert jump_gradual < 0.35 * jump_at_once
    steady = 0.5 * (1 - 0.75) * 3e-5  # the output follows the command this far behind on side +
    assert abs(gradual[-1] - (u[-1] - steady)) < 1.5e-6 and abs(at_once[-1] - (u[-1] - steady)) < 1.5e-6


def test_the_release_setting_is_validated() -> None:
    with pytest.raises(ConfigError, match="'backlash_release' must be >= 0"):
        dataclasses.replace(ControllerConfig(), backlash_release=-0.1).validate()


def test_the_release_changes_nothing_on_a_path_that_never_stands() -> None:
    """Without a freeze nothing is held back: the same offsets, motor bursts included (their
    bound is the inversion's own largest offset, not the wider one a release may need)."""
    offsets = {}
    for release in (0.0, 0.4):
        inv = PlayObserverInverse(PLAY, 0.01, start=1.0, fraction=0.75, learn=True, lead=0.03, freeze=0.5,
                                  motor_burst=True, release=release)
        inv.seed(PLAY, np.zeros(6), np.ones(6, bool), motor_tau=np.full(6, TAU))
        alpha = 1.0 - np.exp(-DT / TAU)
        m, out = np.zeros(6), []
        for k in range(200):
            u = 3 * PLAY * np.sin(2 * np.pi * k * DT / 3.0 + np.arange(6))
            rate = 3 * PLAY * 2 * np.pi / 3.0 * np.cos(2 * np.pi * k * DT / 3.0 + np.arange(6))
            inv.observe(m)
            off = inv.offset(u, DT, rate)
            m = m + alpha * (u + off - m)
            out.append(off)
        offsets[release] = np.array(out)
    assert np.max(np.abs(offsets[0.0])) > 0.5 * 0.75 * PLAY[0]  # the inversion and its bursts acted
    np.testing.assert_array_equal(offsets[0.0], offsets[0.4])
