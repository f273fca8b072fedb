"""The simulated bench as a registration rig: the true plant moved in-process, its images
rendered by the true camera (world_T_left @ T(camera_offset)), the encoders read from the plant."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import home_psi
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.setup import SimSetup, make_plant

Array = NDArray[np.float64]
SETTLE_S = 1.0  # [s] simulated time allowed for each move (actuator lag tau ~ 0.04-0.07 s)


class SimRegistrationRig:
    """:class:`rig.registration.run.RegistrationRig` on the simulated bench."""

    def __init__(self, setup: SimSetup, seed: int = 0) -> None:
        self.setup = setup
        self.plant = make_plant(setup, home_psi(setup.params))
        self.renderer = StereoRenderer(setup.render_camera, setup.marker, noise_preset(setup.rig.render_noise),
                                       seed=seed)
        self._hint = home_psi(setup.params)

    def move_to(self, psi: Array) -> None:
        """Command psi and let the plant settle (the lag is exact; no ramp is needed in simulation)."""
        self.plant.command(actuators_from_psi(self.setup.params, psi))
        self.plant.advance(SETTLE_S)
        self._hint = np.asarray(psi, float)

    def measured_psi(self) -> Array:
        """The configuration the motor encoders report (before backlash)."""
        return psi_from_actuators(self.setup.params, self.plant.measured_actuators(), self._hint)

    def grab(self) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """Render the true arm through the true camera."""
        frame = self.renderer.render(self.plant.true_shape())
        return frame.left, frame.right
