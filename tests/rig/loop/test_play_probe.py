"""The play probe (rig/loop/play_probe.py, solvers/play_probe_fit.py): the fit on a simulated play
operator, the probe in the loop (its own phase, the 6-DoF fallback), the short cubes on the
unseen and the default arm, and a held point that does not buzz."""

import csv
import dataclasses
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wristmark.models.errors import ConfigError
from wristmark.rig.loop.play_probe import NO_POSE, triangle
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.sim.setup import SimSetup, default_config, load_setup
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.play_observer import PlayObserverInverse
from wristmark.solvers.play_probe_fit import fit_play

DT, TAU = 0.06, 0.07  # the loop's cycle and the motor's lag [s]
PLAY_MAX, PLAY = 160e-6, 80e-6  # a backbone's bound and true play [m]


def _probe(play: float, gain: float, noise: float, seed: int, n: int = 10) -> tuple[np.ndarray, np.ndarray, float]:
    """A triangle of 2 x PLAY_MAX through a first-order motor and a play operator; the arm side
    y = c + gain x output + noise, sampled once a cycle (the first before the motor moves)."""
    rng = np.random.default_rng(seed)
    m, o = 0.0, rng.uniform(-0.5, 0.5) * play  # the output anywhere in its band at the start
    ms, ys = [m], [0.01 + gain * o + rng.normal(0.0, noise)]
    first = o
    for u in triangle(n, 2 * PLAY_MAX):
        for _ in range(60):  # 1 ms steps
            m += (1.0 - np.exp(-DT / 60 / TAU)) * (u - m)
            o = float(np.clip(o, m - play / 2, m + play / 2))
        ms.append(m)
        ys.append(0.01 + gain * o + rng.normal(0.0, noise))
    return np.array(ms), np.array(ys), first


def test_triangle_goes_out_back_through_and_returns() -> None:
    t = triangle(8, 1.0)
    assert t[-1] == 0.0 and t.max() == pytest.approx(1.0) and t.min() == pytest.approx(-1.0)
    assert np.argmax(t) < np.argmin(t) and t[-2] < 0.0  # out, back through, returning upwards


@pytest.mark.parametrize("gain", [0.85, 1.0, 1.15])
def test_fit_recovers_the_play_and_a_gain_error_does_not_bias_it(gain: float) -> None:
    """Over 40 noisy probes (5 um of arm-side noise) the fitted play's mean is within 4 % of the
    true one whatever the arm's gain, each fit within 15 um; the gain is the true one and the
    output before the probe is found within 8 um on average (from the few samples before the
    motor reaches the band's edge)."""
    fits = [(fit_play(*_probe(PLAY, gain, 5e-6, s)[:2], PLAY_MAX), _probe(PLAY, gain, 5e-6, s)[2]) for s in range(40)]
    plays = np.array([f.play for f, _ in fits])
    assert all(f.ok for f, _ in fits)
    assert abs(plays.mean() - PLAY) < 0.04 * PLAY and np.abs(plays - PLAY).max() < 15e-6
    assert np.abs([f.gain - gain for f, _ in fits]).max() < 0.05
    before = np.abs([f.first_output - first for f, first in fits])  # the output before the probe moved it
    assert before.mean() < 0.1 * PLAY and before.max() < 0.35 * PLAY


def test_fit_refuses_a_probe_too_noisy_or_too_short() -> None:
    m, y, _ = _probe(PLAY, 1.0, 40e-6, 0)  # noise half the play: the pose cannot resolve it
    assert not fit_play(m, y, PLAY_MAX).ok
    m, y, _ = _probe(PLAY, 1.0, 1e-6, 0)
    assert not fit_play(m / 4, y, PLAY_MAX).ok  # travelled less than the bound
    assert not fit_play(m[:4], y[:4], PLAY_MAX).ok  # too few samples
    assert fit_play(m, y, PLAY_MAX).ok


def test_a_seeded_observer_starts_on_the_probed_side_without_a_burst() -> None:
    """Seeded with a play and an output dragged at the band's lower edge (the probe ended moving
    up), the inversion pushes up at once by fraction x b / 2, with no lead burst."""
    play_max = np.full(6, PLAY_MAX)
    inv = PlayObserverInverse(play_max, 0.01, start=0.15, fraction=0.75, lead=0.03)
    inv.seed(np.full(6, PLAY), np.full(6, -PLAY / 2), np.ones(6, bool))
    inv.observe(np.zeros(6))
    np.testing.assert_array_equal(inv.direction, np.ones(6))
    np.testing.assert_allclose(inv.offset(np.zeros(6), DT), np.full(6, 0.75 * PLAY / 2))


def test_two_readouts_of_one_output_are_weighed_by_their_noise() -> None:
    """The same probe read twice with 20 um of noise each, at different offsets and gains (the
    tip's place and its turn): over 20 probes the fused samples lie nearer the output than either
    readout's alone (in motor units) and the play is fitted closer. A readout the output does not
    move is left out; with none usable the first comes back unchanged."""
    from wristmark.solvers.play_probe_fit import fused_readout

    spread: dict[str, list[float]] = {"place": [], "turn": [], "fused": []}
    miss: dict[str, list[float]] = {"place": [], "turn": [], "fused": []}
    for seed in range(20):
        m, place, _ = _probe(PLAY, 1.0, 20e-6, seed)
        out = _probe(PLAY, 1.0, 0.0, seed)[1] - 0.01  # the same probe's output (the same draws)
        turn = 0.2 + 0.5 * out + np.random.default_rng(100 + seed).normal(0.0, 10e-6, out.size)
        fused = fused_readout(m, [place, turn], PLAY_MAX)
        for name, z in (("place", place - 0.01), ("turn", (turn - 0.2) / 0.5), ("fused", fused)):
            spread[name].append(float(np.std(z - out)))
            miss[name].append(abs(fit_play(m, z, PLAY_MAX).play - PLAY))
    assert np.mean(spread["fused"]) < 0.85 * min(np.mean(spread["place"]), np.mean(spread["turn"])), spread
    assert np.mean(miss["fused"]) < min(np.mean(miss["place"]), np.mean(miss["turn"])), miss
    m, y, _ = _probe(PLAY, 1.0, 5e-6, 0)
    flat = np.full(y.size, 0.3)
    assert np.allclose(fused_readout(m, [y, flat], PLAY_MAX), fused_readout(m, [y], PLAY_MAX))
    assert np.array_equal(fused_readout(m, [flat, np.full(y.size, np.nan)], PLAY_MAX), flat)


@pytest.mark.wallclock
def test_fusing_two_readouts_costs_far_less_than_a_fit() -> None:
    """The probe fits each actuator within one cycle (the box's watchdog wants a command every
    250 ms): the fused readout's weights come from each readout's grid fit, so fusing and then
    fitting costs at most 1.5 x the fit alone (each fitted in full, it was 3.3 x), median of 7."""
    import time

    from wristmark.solvers.play_probe_fit import fused_readout

    m, place, _ = _probe(PLAY, 1.0, 20e-6, 0)
    turn = 0.2 + 0.5 * (_probe(PLAY, 1.0, 0.0, 0)[1] - 0.01)
    alone, fused = [], []
    for _ in range(7):
        t0 = time.perf_counter()
        fit_play(m, place, PLAY_MAX)
        t1 = time.perf_counter()
        fit_play(m, fused_readout(m, [place, turn], PLAY_MAX), PLAY_MAX)
        t2 = time.perf_counter()
        alone.append(t1 - t0)
        fused.append(t2 - t1)
    assert np.median(fused) < 1.5 * np.median(alone), (np.median(fused), np.median(alone))


def test_a_stems_roll_is_read_from_the_tips_turn() -> None:
    """single_tendon's stem roll turns the tip frame about the stem's axis by its own angle
    (w_0 a unit vector) while moving the tip only by the arm's lever (|v_0| a few mm per rad):
    a measured turn of 2 mrad about w_0 reads the roll 2 mrad on; a turn over TURN_MAX, or no
    orientation, reads nothing."""
    from scipy.spatial.transform import Rotation

    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.rig.loop.play_probe import TURN_MAX, TipProjection
    from wristmark.rig.loop.servo_session import PointHold
    from wristmark.rig.targets.orientation_path import start_configuration
    from wristmark.rig.targets.trajectories import workspace_centre

    setup = load_setup(robot=CONFIG_DIR / "robots" / "single_tendon.yaml")
    psi0 = start_configuration(setup.params, PointHold(np.array([workspace_centre(setup.params)]), 1.0, hold=0.6)
                               .sample(0.0)[0])
    proj = TipProjection(setup.params, psi0)
    assert abs(np.linalg.norm(proj.w[0]) - 1.0) < 1e-3 and np.linalg.norm(proj.v[0]) < 0.02
    R0 = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix()
    assert proj.turn(0, R0) == pytest.approx(proj.a0[0])  # the first orientation read is the reference
    turned = Rotation.from_rotvec(0.002 * proj.w[0] / np.linalg.norm(proj.w[0])).as_matrix() @ R0
    assert proj.turn(0, turned) == pytest.approx(proj.a0[0] + 0.002, abs=2e-5)
    far = Rotation.from_rotvec(1.5 * TURN_MAX * np.array([1.0, 0.0, 0.0])).as_matrix() @ R0
    assert np.isnan(proj.turn(0, far)) and np.isnan(proj.turn(0, None))


def test_config_rejects_bad_probe_keys() -> None:
    with pytest.raises(ConfigError, match="play_probe_amplitude"):
        ControllerConfig(play_probe_amplitude=0.5).validate()
    with pytest.raises(ConfigError, match="play_probe_time"):
        ControllerConfig(play_probe_time=0.0).validate()
    with pytest.raises(ConfigError, match="backlash_freeze"):
        ControllerConfig(backlash_freeze=-1.0).validate()


def _setup(plant: str, controller: str = "controller.yaml") -> SimSetup:
    setup = load_setup(plant=default_config(plant), controller=default_config(controller),
                       marker=default_config("marker_coded.yaml"))
    return setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"))


def _cube(setup: SimSetup, duration: float, seed: int = 0, orientation: str = "hold") -> tuple[dict, list[str]]:
    """A short cube's closed-loop summary and the phase of every logged cycle."""
    from wristmark.sim.experiments import run_cube

    with tempfile.TemporaryDirectory() as tmp:
        res = run_cube(setup, Path(tmp), progress=False, duration=duration, seed=seed, orientation=orientation)
        with open(Path(tmp) / "log.csv") as f:
            phases = [r["phase"] for r in csv.DictReader(f)]
    return res["closed_loop"], phases


@pytest.mark.slow
def test_probe_is_its_own_phase_and_cuts_the_unseen_arms_start() -> None:
    """The default controller on configs/plant_unseen.yaml (truth-noise, orientation held, the
    first 8 s of the cube, the start and the first corner, where the max was): the probe's
    cycles are logged as closed_loop:probe (6 x 11 + 3) and not counted; the max is below 1 mm
    and below the same controller's without the probe (configs/controller_encoders.yaml)."""
    with_probe, phases = _cube(_setup("plant_unseen.yaml"), 8.0)
    without, phases_without = _cube(_setup("plant_unseen.yaml", "controller_encoders.yaml"), 8.0)
    assert phases.count("closed_loop:probe") == 6 * 11 + 3 and "closed_loop:probe" not in phases_without
    assert with_probe["cycles"] == without["cycles"] == phases.count("closed_loop")
    assert with_probe["max_mm"] < 1.0 and with_probe["max_mm"] < 0.9 * without["max_mm"]


def test_default_controller_does_not_hurt_the_default_arm() -> None:
    """configs/plant.yaml, the first 16 s of the cube, orientation free: the default controller's
    mean and max are within the issue's bound for the default arm (0.18 / 0.86 mm with vision;
    truth-noise here is noisier: 0.25 / 0.86)."""
    res, _ = _cube(_setup("plant.yaml"), 16.0, orientation="none")
    assert res["mean_mm"] <= 0.25 and res["max_mm"] <= 0.86


class _PositionOnly:
    """A tip sensor that drops the orientation (as the reference marker's tracker gives)."""

    def __init__(self, inner: object) -> None:
        self.inner = inner

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        m = self.inner.measure(frame, axis_hint_world)  # type: ignore[attr-defined]
        return dataclasses.replace(m, R_world=None, roll_known=False)


def test_without_a_six_dof_pose_the_probe_is_skipped_and_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    """A tracker without orientation: one line on stderr, nothing probed, the play learnt online."""
    from wristmark.rig.loop.servo_session import PointHold
    from wristmark.rig.recording.run_log import RunLog
    from wristmark.rig.targets.orientation_path import start_configuration
    from wristmark.rig.targets.trajectories import workspace_centre
    from wristmark.sim.setup import make_direct_loop

    setup = _setup("plant_unseen.yaml")
    traj = PointHold(np.array([workspace_centre(setup.params)]), 1.0, hold=0.6)
    loop = make_direct_loop(setup, start_configuration(setup.params, traj.sample(0.0)[0]), closed_loop=True, seed=0)
    loop.sensor = _PositionOnly(loop.sensor)
    ctrl = loop.controller
    assert ctrl is not None and ctrl.wants_play_probe
    started: list[object] = []
    start_play = ctrl.start_play

    def spy(fits: object, *args: object) -> object:
        started.append(fits)
        return start_play(fits, *args)  # type: ignore[arg-type]

    ctrl.start_play = spy  # type: ignore[method-assign,assignment]
    log = RunLog()
    loop.run(traj, "point", True, log, settle=0.6)
    assert loop.play_probe_note == NO_POSE and loop.play_fits is None
    assert started == [None] and not ctrl.wants_play_probe  # not seeded: the play is learnt online
    assert not [r for r in log.records if r.phase == "point:probe"] and log.phase("point")


class _RollUnreadAt:
    """A tip sensor whose ``at``-th measurement (from 1) has its roll code unread, as a coded
    sleeve's tracker gives now and then (the orientation modulo one column)."""

    def __init__(self, inner: object, at: int) -> None:
        self.inner, self.at, self.calls = inner, at, 0

    def measure(self, frame: object, axis_hint_world: object = None) -> TipMeasurement:
        self.calls += 1
        m = self.inner.measure(frame, axis_hint_world)  # type: ignore[attr-defined]
        return dataclasses.replace(m, roll_known=False) if self.calls == self.at else m


def test_one_settle_cycle_without_the_roll_code_does_not_skip_the_probe() -> None:
    """The settle's last measurement has its roll unread (the cycles before it had it): the probe
    still runs and fits every actuator (a 6-DoF pose in the settle's last cycles is enough),
    where it was once skipped for that one cycle (a scene lab's flaky test)."""
    from wristmark.rig.loop.servo_session import PointHold
    from wristmark.rig.recording.run_log import RunLog
    from wristmark.rig.targets.orientation_path import start_configuration
    from wristmark.rig.targets.trajectories import workspace_centre
    from wristmark.sim.setup import make_direct_loop

    setup = _setup("plant_unseen.yaml")
    traj = PointHold(np.array([workspace_centre(setup.params)]), 1.0, hold=0.6)
    n_settle = int(round(0.6 / setup.rig.control_dt))
    fits, logs = [], []
    for at in (n_settle, 0):  # the settle's last measurement without its roll, then none
        loop = make_direct_loop(setup, start_configuration(setup.params, traj.sample(0.0)[0]), closed_loop=True,
                                seed=0)
        loop.sensor = _RollUnreadAt(loop.sensor, at)
        logs.append(RunLog())
        loop.run(traj, "point", True, logs[-1], settle=0.6)
        assert loop.play_probe_note == "" and isinstance(loop.play_fits, list) and len(loop.play_fits) == 6
        fits.append(loop.play_fits)
    phases = [r.phase for r in logs[0].records]
    assert phases[:n_settle + 1] == ["point:settle"] * n_settle + ["point:probe"]  # roll dropped on the settle's last
    assert fits[0] == fits[1] and sum(f.ok for f in fits[0]) >= 4  # the same probe as with the roll read


def _hold_point(robot: str, from_tip: bool, sensor: str = "vision") -> tuple[Any, SimSetup, list]:
    """A point held on a shipped arm with its plant file and the reference marker (the controller's
    ``play_probe_from_tip`` as given): the loop, its setup and the log's probe cycles."""
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.rig.loop.servo_session import PointHold
    from wristmark.rig.recording.run_log import RunLog
    from wristmark.rig.targets.orientation_path import start_configuration
    from wristmark.rig.targets.trajectories import workspace_centre
    from wristmark.sim.setup import make_direct_loop

    setup = load_setup(robot=CONFIG_DIR / "robots" / f"{robot}.yaml")
    setup = setup.with_changes(controller=dataclasses.replace(setup.controller, play_probe_from_tip=from_tip),
                               rig=dataclasses.replace(setup.rig, sensor=sensor))
    traj = PointHold(np.array([workspace_centre(setup.params)]), 1.0, hold=0.6)
    loop = make_direct_loop(setup, start_configuration(setup.params, traj.sample(0.0)[0]), closed_loop=True, seed=0)
    log = RunLog()
    loop.run(traj, "point", True, log, settle=0.6)
    return loop, setup, [r for r in log.records if r.phase == "point:probe"]


def _probe_point(robot: str) -> tuple[list, np.ndarray, list]:
    """The probe from the tip on a held point (vision in the loop): its fits, the plant's plays
    and the log's probe cycles."""
    loop, setup, probe_cycles = _hold_point(robot, from_tip=True)
    assert loop.play_fits is not None and loop.play_probe_note == "", loop.play_probe_note
    return loop.play_fits, np.asarray(setup.plant.backlash, float), probe_cycles


def test_by_default_an_arm_whose_pose_does_not_give_its_actuators_is_not_probed() -> None:
    """single_tendon with the default controller (play_probe_from_tip off): skipped with a note
    that names the key, nothing probed."""
    from wristmark.rig.loop.play_probe import FEW_JOINTS

    loop, _, probe_cycles = _hold_point("single_tendon", from_tip=False, sensor="truth-noise")
    assert loop.play_fits is None and loop.play_probe_note == FEW_JOINTS and "play_probe_from_tip" in FEW_JOINTS
    assert not probe_cycles


def test_an_arm_with_fewer_joints_than_a_pose_is_probed_from_the_tip() -> None:
    """single_tendon (4 joints, 6 actuators: stem roll, feed, 4 tendons), the reference marker,
    ``play_probe_from_tip``: each actuator's output read from the tip's place and turn alone
    (play_probe.TipProjection). Measured 2026-12-07 at seeds 0-5: stem roll 7.4-8.6 mrad of 8
    (read from the tip's place alone, 6.5-10.0 mrad, and refused as too noisy at 4 of the 6
    seeds), feed and tendons within 4 % of 100 and 50 um."""
    fits, true, probe_cycles = _probe_point("single_tendon")
    got = np.array([f.play for f in fits])
    assert len(fits) == true.size == 6 and all(f.ok for f in fits) and probe_cycles
    assert np.all(np.abs(got[1:] - true[1:]) <= 0.05 * true[1:]), (got, true)
    assert abs(got[0] - true[0]) <= 0.1 * true[0], (got, true)


def test_a_tendon_arm_with_coupled_segments_is_probed_from_the_tip() -> None:
    """tendon3 (7 joints, 10 actuators: feed and 9 tendons through the proximal segments): every
    tendon's fit holds, between its plant play and 1.5 x it (the coupled segments' stiffness
    adds to the dead band what the probe sees: 58-70 um of 50 measured 2026-12-03; the feed 109
    um of 100)."""
    fits, true, probe_cycles = _probe_point("tendon3")
    got = np.array([f.play for f in fits])
    assert len(fits) == true.size == 10 and all(f.ok for f in fits) and probe_cycles
    assert np.all(got >= 0.95 * true) and np.all(got <= 1.5 * true), (got, true)


def _overestimating_probe(monkeypatch: pytest.MonkeyPatch, plays: dict[int, float]) -> None:
    """Make the probe report ``plays`` (actuator index -> play [m]) as trusted fits, as a probe on a
    loaded host did (docs/notes/play-probe.md)."""
    from wristmark.rig.loop import play_probe

    fit, probed = play_probe.fit_play, []

    def overestimated(motor: np.ndarray, arm: np.ndarray, play_max: float) -> Any:
        j = len(probed) % 6
        probed.append(j)
        f = fit(motor, arm, play_max)
        return dataclasses.replace(f, play=plays[j], ok=True) if j in plays else f

    monkeypatch.setattr(play_probe, "fit_play", overestimated)


@pytest.mark.slow
def test_a_play_the_probe_overestimates_is_shrunk_as_the_feedback_buzzes_across_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """configs/plant.yaml (30 um per backbone), its s1b and s2b probed at 87 um: the inversion
    overshoots each change of side and the feedback turns them back and forth. Shrinking a play
    the feedback alone turns for the third time within backlash_buzz_time brings the cube near
    the truly probed one (truth-noise, the first 16 s of the cube)."""
    setup = _setup("plant.yaml")
    probed, _ = _cube(setup, 16.0, orientation="none")
    _overestimating_probe(monkeypatch, {3: 8.7e-5, 5: 8.7e-5})
    off = setup.with_changes(controller=dataclasses.replace(setup.controller, backlash_buzz_time=0.0))
    kept, _ = _cube(off, 16.0, orientation="none")
    shrunk, _ = _cube(setup, 16.0, orientation="none")
    print(f"probed {probed['mean_mm']:.3f} / {probed['max_mm']:.3f} mm ({probed['play_shrinks']} shrinks), "
          f"kept {kept['mean_mm']:.3f} / {kept['max_mm']:.3f} mm, shrunk {shrunk['mean_mm']:.3f} / "
          f"{shrunk['max_mm']:.3f} mm ({shrunk['play_shrinks']} shrinks)")
    assert kept["play_shrinks"] == 0 and shrunk["play_shrinks"] >= 3
    assert kept["mean_mm"] > 2.0 * probed["mean_mm"]  # the buzz: 0.42 against 0.18 mm
    # shrunk within the walk's first seconds: the mean near the truly probed run's, the max (the
    # buzz before the shrinks) well under the kept play's (0.21 / 1.08 mm, 2026-12-05)
    assert shrunk["mean_mm"] < 1.25 * probed["mean_mm"] and shrunk["mean_mm"] < 0.6 * kept["mean_mm"]
    assert shrunk["max_mm"] < 0.85 * kept["max_mm"]
