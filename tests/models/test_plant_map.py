"""The plant's static map (models/plant_map.py): the simulated true arm bends through it, and
its inverse puts the identified arm's tip where the nominal model's is."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.plant_map import plant_command, plant_tip, true_arm
from wristmark.models.plant_params import PlantParams
from wristmark.models.robot_params import RobotParams

ARM = RobotParams()
PLANT = PlantParams(bend_gain=(1.06, 0.88), plane_offset=(-0.06, 0.08), stem_coupling=0.04,
                    tip_force=(0.03, 0.05, -0.08), segment_stiffness=(0.35, 0.12))
PSI = np.array([0.1, 0.04, 0.7, 0.3, 0.9, -0.4])


def test_the_simulated_arm_bends_through_the_map() -> None:
    from wristmark.sim.plant import TruePlant

    plant = TruePlant(ARM, PLANT, psi0=PSI)
    assert plant.true_tip() == pytest.approx(plant_tip(true_arm(ARM, PLANT), PLANT, PSI), abs=1e-12)


def test_the_inverse_reaches_the_nominal_tip_within_ten_micrometres() -> None:
    target = forward_kinematics(ARM, PSI).tip
    assert np.linalg.norm(plant_tip(ARM, PLANT, PSI) - target) > 5e-3  # the errors are real (> 5 mm)
    q = plant_command(ARM, PLANT, PSI)
    assert np.linalg.norm(plant_tip(ARM, PLANT, q) - target) < 1e-5
    assert np.all(np.isfinite(actuators_from_psi(ARM, q)))


def test_the_ideal_plant_is_its_own_inverse() -> None:
    assert plant_command(ARM, PlantParams(), PSI) == pytest.approx(PSI, abs=1e-12)
