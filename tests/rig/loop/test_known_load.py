"""A known weight during the excitation (rig/loop/known_load.py): where the plan hangs it; on
hardware the prompt holds the arm with the actuator box fed (its 250 ms watchdog never trips
however long the person takes), refuses a closed stdin in one line, and the excitation's clock
goes on from the moment the weight hangs (no ramp rushed to catch up)."""

from __future__ import annotations

import io
import os
import threading
import time

import numpy as np
import pytest

from tests.rig.link.test_serial_link import open_bench
from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams
from wristmark.rig.loop.excitation import excitation_plan
from wristmark.rig.loop.known_load import KnownLoadPrompt, load_force, with_known_load

F = np.array([0.0, 0.0, -0.15])


def test_the_bench_hangs_it_at_every_other_pose_and_hardware_in_one_block() -> None:
    plan = excitation_plan(RobotParams(), np.full(6, 1e-4), poses=8, seed=1)
    alternate, block = with_known_load(plan, F), with_known_load(plan, F, block=True)
    assert alternate.loads is not None and block.loads is not None
    np.testing.assert_array_equal(alternate.loads[:, 2], [0, -0.15, 0, -0.15, 0, -0.15, 0, -0.15])
    np.testing.assert_array_equal(block.loads[:, 2], [0, 0, 0, 0, -0.15, -0.15, -0.15, -0.15])
    np.testing.assert_allclose(load_force(0.3, np.array([0.0, 2.0, 0.0])), [0.0, 0.3, 0.0])
    with pytest.raises(InputError, match="direction"):
        load_force(0.3, np.zeros(3))


@pytest.mark.wallclock
def test_the_prompt_holds_the_arm_with_the_box_fed_until_enter() -> None:
    b = open_bench(simulated=False)
    r, w = os.pipe()
    ask = os.fdopen(r, "r")
    tell = io.StringIO()
    try:
        prompt = KnownLoadPrompt(b.link, ask=ask, tell=tell, settle=0.3)
        threading.Timer(0.8, lambda: os.write(w, b"\n")).start()  # the person takes 0.8 s (> 3 watchdogs)
        t0 = time.monotonic()
        prompt(F)
        assert time.monotonic() - t0 >= 1.05  # 0.8 s for Enter + 0.3 s to settle
        assert "hang 0.15 N (15.3 g)" in tell.getvalue() and "press Enter" in tell.getvalue()
        assert b.emulator.enabled and not b.emulator.watchdog_tripped
        prompt(F)  # the same weight: nothing asked
        assert tell.getvalue().count("press Enter") == 1
        os.close(w)  # nobody at the keyboard any more
        with pytest.raises(InputError, match="stdin is closed"):
            prompt(np.zeros(3))
    finally:
        ask.close()
        b.link.close()
        b.emulator.stop()


def test_the_excitation_goes_on_from_when_the_weight_hangs() -> None:
    """However long the person took (here 5 s of the arm's time), the cycles after the pause go
    on from then, one control cycle apart: no ramp is rushed through to catch up."""
    import dataclasses

    from wristmark.rig.link.actuator_link import DirectLink
    from wristmark.rig.loop.excitation import run_excitation
    from wristmark.sim.identify_bench import bench_plan
    from wristmark.sim.setup import load_setup, make_measurement, make_plant

    setup = load_setup()
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"))
    plan = with_known_load(bench_plan(setup, 8), F, block=True)
    plant = make_plant(setup, plan.poses[0])
    link = DirectLink(plant)
    frames, sensor = make_measurement(setup, plant, lambda: link.time, 0)
    pauses: list[float] = []

    def person(force: np.ndarray) -> None:
        if np.any(force) and not pauses:
            pauses.append(link.time)
            link.advance_to(link.time + 5.0)

    data = run_excitation(setup.params, link, frames, sensor, plan, setup.rig.control_dt, apply_load=person)
    dt = np.diff(data.times)
    assert len(pauses) == 1 and np.sum(dt > 4.9) == 1  # one gap: the pause
    np.testing.assert_allclose(dt[dt < 4.9], setup.rig.control_dt, rtol=1e-9)
    assert data.loads is not None and np.count_nonzero(data.loads[:, 2]) > 0
