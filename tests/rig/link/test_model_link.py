"""The link through the identified arm (rig/link/model_link.py): open loop, nominal targets sent
through it reach the nominal model's tip on an arm with the identified errors, where sent
directly they miss by millimetres; the encoders come back as the nominal model sees them."""

from __future__ import annotations

import numpy as np

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.plant_params import PlantParams
from wristmark.models.robot_params import RobotParams
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.link.model_link import ModelLink
from wristmark.sim.plant import TruePlant

ARM = RobotParams()
TRUE = PlantParams(bend_gain=(1.06, 0.88), plane_offset=(-0.06, 0.08), stem_coupling=0.04,
                   backlash=(0.006, 8e-5, 8e-5, 8e-5, 7e-5, 7e-5), actuator_tau=0.07)
PSI0 = np.array([0.0, 0.04, 0.7, 0.0, 0.9, 0.0])


def walk(link_of: type | None) -> float:
    """Largest tip error [m] over the second half of a slow circle of the stem rotation and bends
    (targets every 60 ms)."""
    plant = TruePlant(ARM, TRUE, psi0=PSI0)
    link = DirectLink(plant) if link_of is None else ModelLink(DirectLink(plant), ARM, TRUE, 0.06, plays=True)
    errs = []
    for k in range(200):
        psi = PSI0 + np.array([0.1 * np.sin(k / 30), 0.0, 0.1 * np.sin(k / 20), 0.3 * np.cos(k / 25), 0.0, 0.0])
        link.send_target(actuators_from_psi(ARM, psi))
        link.advance_to(0.06 * (k + 1))
        if k > 100:
            nxt = forward_kinematics(ARM, psi).tip
            errs.append(np.linalg.norm(plant.true_tip() - nxt))
    return float(max(errs))


def test_the_identified_inverse_removes_most_of_the_open_loop_error() -> None:
    direct, modelled = walk(None), walk(ModelLink)
    assert direct > 3e-3
    assert modelled < 0.1 * direct


def test_encoders_are_shifted_to_the_nominal_model() -> None:
    plant = TruePlant(ARM, TRUE, psi0=PSI0)
    link = ModelLink(DirectLink(plant), ARM, TRUE, 0.06)
    a = actuators_from_psi(ARM, PSI0)
    link.send_target(a)
    link.advance_to(2.0)
    assert np.abs(link.measured_actuators() - a).max() < 1e-6  # settled: reads the nominal target
    assert np.abs(plant.measured_actuators() - a).max() > 1e-4  # while the motors sit elsewhere
