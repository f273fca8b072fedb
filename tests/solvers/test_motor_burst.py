"""The motor's lag measured by the play probe and the reversal's burst sized from it
(``backlash_motor_burst``: solvers/play_probe_fit.py ``fit_motor_lag``, solvers/play_observer.py)."""

import dataclasses
import math

import numpy as np
import pytest

from tests import old_defaults
from wristmark.models.errors import ConfigError
from wristmark.models.units import on_micro_grid
from wristmark.rig.loop.play_probe import triangle
from wristmark.solvers.play_observer import PlayObserverInverse
from wristmark.solvers.play_probe_fit import fit_motor_lag

DT = 0.06
PLAY = np.array([0.006, 8e-5, 1e-4, 8e-5, 1e-4, 7e-5])


def _lagged(m: np.ndarray, target: np.ndarray, tau: float, t: float, steps: int = 60) -> np.ndarray:
    alpha = 1.0 - math.exp(-t / steps / tau)
    for _ in range(steps):
        m = m + alpha * (target - m)
    return m


@pytest.mark.parametrize("tau", [0.03, 0.075])
def test_the_probe_measures_the_motor_lag_from_the_encoders(tau: float) -> None:
    """A probe's triangle (10 cycles of 60 ms, targets sent right after each reading) through a
    first-order motor, read in micro-units: the fitted lag is the motor's within 3 %; a command
    that does not move gives no lag."""
    offsets = triangle(10, 2 * 1.6e-4)
    m, times, reads, sends, targets = 0.0, [], [], [], []
    for i in range(11):
        times.append(i * DT)
        reads.append(float(on_micro_grid(np.array([m]))[0]))
        if i < 10:
            sends.append(i * DT)
            targets.append(float(offsets[i]))
            m = float(_lagged(np.array([m]), np.array([offsets[i]]), tau, DT)[0])
        else:
            m = float(_lagged(np.array([m]), np.array([targets[-1]]), tau, DT)[0])
    fitted = fit_motor_lag(np.array(sends), np.array(targets), np.array(times), np.array(reads))
    assert fitted == pytest.approx(tau, rel=0.03)
    flat = fit_motor_lag(np.array(sends), np.zeros(10), np.array(times), np.zeros(11))
    assert math.isnan(flat)


def _reversal(tau: float, burst: bool) -> float:
    """A ramp of the nominal command up for 1.2 s then down, through a first-order motor of lag
    ``tau`` and the true play, inverted at 0.75 with a 30 ms lead (and, with ``burst``, the
    probed lag); the output's mean error [x play] over the 0.3 s after the reversal (the worst actuator)."""
    inv = PlayObserverInverse(2 * PLAY, 0.01, start=0.5, fraction=0.75, learn=False, lead=0.03, motor_burst=burst)
    inv.seed(PLAY, np.zeros(6), np.ones(6, bool), relearn=False, motor_tau=np.full(6, tau))
    rate = PLAY / 0.25  # the command crosses a play in 0.25 s
    m, y, err = np.zeros(6), np.zeros(6), []
    for k in range(40):
        t = k * DT
        u = rate * (t if t <= 1.2 else 2.4 - t)
        inv.observe(m)
        target = u + inv.offset(u, DT)
        for _ in range(60):
            m = _lagged(m, target, tau, DT / 60, steps=1)
            y = np.clip(y, m - PLAY / 2, m + PLAY / 2)
        u_end = rate * ((t + DT) if t + DT <= 1.2 else 2.4 - t - DT)
        if 1.2 < t + DT <= 1.5:
            err.append(np.abs(y - u_end) / PLAY)
    return float(np.max(np.mean(err, axis=0)))


@pytest.mark.parametrize("tau", [0.075, 0.09])
def test_a_burst_sized_to_the_motor_lag_crosses_the_play_sooner(tau: float) -> None:
    """A slow motor (75-90 ms against the 60 ms cycle, the lead assumes ~30 ms) reversing through
    its play: with the burst sized from the encoders and the probed lag, the output's mean error
    after the reversal is at most 0.92 x the one with the lead's fixed burst (0.89-0.90 x)."""
    lead_only = _reversal(tau, burst=False)
    sized = _reversal(tau, burst=True)
    assert sized <= 0.92 * lead_only, (sized, lead_only)


def test_without_a_measured_lag_the_burst_is_the_leads() -> None:
    """No lag from the probe (NaN): the offsets are exactly the lead's."""
    a = PlayObserverInverse(PLAY, 0.01, start=1.0, fraction=0.75, learn=False, lead=0.03, motor_burst=True)
    b = PlayObserverInverse(PLAY, 0.01, start=1.0, fraction=0.75, learn=False, lead=0.03, motor_burst=False)
    for inv in (a, b):
        inv.seed(PLAY, np.zeros(6), np.ones(6, bool), relearn=False, motor_tau=np.full(6, np.nan))
    m = np.zeros(6)
    for k in range(40):
        u = PLAY * 3 * math.sin(k * DT * 2.0)
        for inv in (a, b):
            inv.observe(m)
        oa, ob = a.offset(np.full(6, u), DT), b.offset(np.full(6, u), DT)
        np.testing.assert_array_equal(oa, ob)
        m = _lagged(m, u + oa, 0.07, DT)


def test_motor_burst_key_is_validated_and_reaches_the_inversion() -> None:
    base = old_defaults.controller(kind="qp", backlash_compensation=True, backlash_method="encoders", play_probe=True)
    dataclasses.replace(base, backlash_motor_burst=True).validate()
    with pytest.raises(ConfigError, match="backlash_motor_burst"):
        dataclasses.replace(base, backlash_method="schmitt", backlash_motor_burst=True).validate()
    from wristmark.solvers.controller import make_inverse

    inv = make_inverse(dataclasses.replace(base, backlash_motor_burst=True))
    assert isinstance(inv, PlayObserverInverse) and inv.motor_burst


def test_the_loop_hands_the_probed_lag_to_the_inversion() -> None:
    """The default controller file on plant_unseen (70 ms motors), truth-noise, a 1 s walk:
    every actuator's probed lag is within 3 % of the plant's and the inversion has it."""
    from wristmark.rig.recording.run_log import RunLog
    from wristmark.rig.targets.orientation_path import start_configuration
    from wristmark.rig.targets.trajectories import CUBE_SIZE, CUBE_SPEED, cube_trajectory, workspace_centre
    from wristmark.sim.setup import load_setup, make_direct_loop

    setup = load_setup(marker="configs/marker_coded.yaml", plant="configs/plant_unseen.yaml")
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise", seed=0))
    assert setup.controller.backlash_motor_burst
    traj = cube_trajectory(workspace_centre(setup.params), CUBE_SIZE, CUBE_SPEED).truncated(1.0)
    traj = traj.with_orientation("hold", setup.params)
    loop = make_direct_loop(setup, start_configuration(setup.params, traj.sample(0.0)[0]), closed_loop=True)
    loop.run(traj, "closed_loop", True, RunLog(), settle=setup.rig.settle_time, progress=False)
    assert loop.play_fits is not None and loop.controller is not None and loop.controller.compensator is not None
    taus = np.array([f.motor_tau for f in loop.play_fits])
    np.testing.assert_allclose(taus, setup.plant.actuator_tau, rtol=0.03)
    inv = loop.controller.compensator.inverse
    assert isinstance(inv, PlayObserverInverse)
    np.testing.assert_allclose(inv.motor_tau, taus)
