"""A simulated camera whose frames are old: the plant's memory of its shape, the rendered
source's aged frames, and the in-process loop's capture -> command latency with them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.actuation import actuators_from_psi
from wristmark.models.errors import InputError
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.render.rendered_source import RenderedStereoSource
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.setup import load_setup

PARAMS = RobotParams()
HOME = np.array(HOME_PSI)


def _moving_plant(history: float) -> tuple[TruePlant, list[tuple[float, np.ndarray]]]:
    """A plant with play and lag driven through a reversal; its tip logged every 3 ms."""
    plant = TruePlant(PARAMS, PlantParams(actuator_tau=0.04, backlash=[0.01, 2e-4, 2e-4, 2e-4, 2e-4, 2e-4]),
                      psi0=HOME, history=history)
    tips = [(plant.time, plant.true_tip())]
    for k, dq in enumerate((0.2, -0.3)):
        psi = HOME.copy()
        psi[2] += dq
        psi[4] -= dq
        plant.command(actuators_from_psi(PARAMS, psi))
        for _ in range(40 + 10 * k):
            plant.advance(0.003)
            tips.append((plant.time, plant.true_tip()))
    return plant, tips


def test_the_plant_gives_its_shape_at_an_earlier_instant() -> None:
    plant, tips = _moving_plant(history=0.2)
    now = plant.time
    checked = 0
    for t, tip in tips:
        if t >= now - 0.2:  # within the history it keeps: the same shape it had then
            np.testing.assert_allclose(plant.true_shape_at(t).tip, tip, rtol=0, atol=1e-9)
            checked += 1
    assert checked > 50
    # between two of its steps: between the shapes there (the tip moves smoothly over 0.5 ms)
    (t0, a), (t1, b) = tips[-20], tips[-19]
    mid = plant.true_shape_at(t0 + 0.5 * (t1 - t0)).tip
    assert np.linalg.norm(mid - 0.5 * (a + b)) < 0.05 * np.linalg.norm(b - a) + 1e-9
    assert np.linalg.norm(b - a) > 1e-6  # the arm was moving there
    np.testing.assert_allclose(plant.true_shape_at(now + 1.0).tip, plant.true_tip(), atol=0)


def test_an_instant_beyond_the_history_is_refused() -> None:
    plant, _ = _moving_plant(history=0.05)
    with pytest.raises(InputError, match="history"):
        plant.true_shape_at(plant.time - 0.2)
    without, _ = _moving_plant(history=0.0)
    with pytest.raises(InputError, match="history"):
        without.true_shape_at(without.time - 0.01)


def test_an_aged_source_renders_the_arm_as_it_was_and_stamps_it_so() -> None:
    setup = load_setup()
    plant, _ = _moving_plant(history=0.2)
    cam = scaled_stereo_camera(setup.render_camera, 0.35)
    now_src = RenderedStereoSource(plant, cam, setup.marker, lambda: 10.0 + plant.time, noise="none")
    old_src = RenderedStereoSource(plant, cam, setup.marker, lambda: 10.0 + plant.time, noise="none", age=0.06)
    old = old_src.read()
    assert old.t_capture == pytest.approx(10.0 + plant.time - 0.06)
    then = StereoRenderer(cam, setup.marker, noise_preset("none")).render(plant.true_shape_at(plant.time - 0.06))
    assert np.array_equal(then.left, old.left)
    assert not np.array_equal(now_src.read().left, old.left)  # the arm moved in those 60 ms


def test_the_in_process_loop_measures_frames_that_old() -> None:
    from wristmark.cli import servo as S
    from wristmark.rig.loop.servo_summary import summarize
    from wristmark.sim.servo_bench import open_sim_session

    setup = load_setup()
    rig = dataclasses.replace(setup.rig, image_scale=0.35, control_dt=0.1, vision_latency=0.02, frame_age=0.09,
                              settle_time=0.5)
    setup = setup.with_changes(rig=rig)
    traj = S.build_trajectory(setup, "cube", None, 1.5)
    psi0 = S.start_configuration(setup, traj)
    session = open_sim_session(setup, psi0, S.LinkOptions(kind="direct"), seed=0)
    out = S.run_servo(setup, traj, session, psi0, settle=rig.settle_time)
    recs = [r for r in out.log.records if r.meas_ok]
    assert len(recs) > 15
    for r in recs:
        assert r.t_capture == pytest.approx(r.t - 0.09, abs=1e-9)
        assert r.latency_ms == pytest.approx(110.0, abs=1e-6)
    c = summarize(setup, traj, session, out)["closed_loop"]
    assert c["noise_free"]["mean_mm"] < 1.0  # the loop closes on the old frames
