"""The loop on an identified arm (rig/loop/model_loop.py): the link inverts the motors' lag, so
the loop drops its feed-forward lead and its delay compensation reaches each command one cycle
after its send along the identified lag (on the wall clock, a frame captured after its cycle's
start was moved back by nothing before, and the arm trailed its path by ~20 ms)."""

from __future__ import annotations

import numpy as np

from wristmark.models.plant_params import PlantParams
from wristmark.models.robot_params import RobotParams
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.link.model_link import ModelLink
from wristmark.rig.loop.model_loop import model_rig, use_model
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.sim.plant import TruePlant
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller

ARM = RobotParams()
MODEL = PlantParams(bend_gain=(1.06, 0.88), actuator_tau=0.07)


def test_the_model_rig_reaches_each_command_a_cycle_after_it_went_out() -> None:
    rig = model_rig(RigConfig(control_dt=0.05), MODEL)
    assert rig.feedforward_lead == 0.0
    assert rig.delay_compensation_tau == 0.07
    assert rig.delay_compensation_reach == 0.05
    assert RigConfig().delay_compensation_reach == 0.0  # without a model: the lag alone


def test_use_model_hands_the_dead_band_over_and_wraps_the_link() -> None:
    controller = make_controller(ARM, ControllerConfig())
    link = use_model(DirectLink(TruePlant(ARM, MODEL, psi0=np.array([0.0, 0.04, 0.7, 0.0, 0.9, 0.0]))),
                     ARM, MODEL, controller, 0.06)
    assert isinstance(link, ModelLink) and link.plays and link.cycle == 0.06
