"""The servo loop on an identified arm (``--model``, docs/identification.md): its link commands
the identified arm's inverse (rig/link/model_link.py) and its controller's dead-band inversion
starts from the identified plays and lags: the play probe then moves each actuator through its
triangle as usual but needs no pose (the reference sleeve gets what only the coded sleeve's
measured probe gave), the output's place in the band following from the identified play and the
encoders alone."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm
from wristmark.models.plant_params import PlantParams
from wristmark.rig.link.actuator_link import ActuatorLink
from wristmark.rig.link.model_link import ModelLink
from wristmark.solvers.controller import Controller
from wristmark.solvers.identification import play_outputs
from wristmark.solvers.play_probe_fit import PlayFit

Array = NDArray[np.float64]
__all__ = ["use_model", "model_play_fit"]


def use_model(link: ActuatorLink, params: Arm, model: PlantParams, controller: Controller | None) -> ModelLink:
    """``link`` through the identified arm ``model``'s inverse; open loop (no controller) the
    link also inverts the identified plays and lag, closed loop the controller's inversion is
    seeded with them (its play probe then needs no pose)."""
    if controller is not None:
        controller.model_fits = [PlayFit(play=float(b), gain=1.0, offset=0.0, first_output=float("nan"),
                                         last_output=float("nan"), residual_rms=0.0, ok=True,
                                         motor_tau=float(model.actuator_tau))
                                 for b in model.backlash]
    return ModelLink(link, params, model, dynamics=controller is None)


def model_play_fit(model: PlayFit, motor: Array, command: float) -> PlayFit:
    """One actuator's probe "fit" from the identified play: the output run through the probe's
    encoder samples ``motor`` (its triangle goes past the play both ways, so the output's start
    does not matter), the output before the probe taken as the settled ``command``."""
    out = play_outputs(np.asarray(motor, float)[:, None], np.array([model.play]))[:, 0]
    return PlayFit(play=model.play, gain=1.0, offset=0.0, first_output=command,
                   last_output=float(out[-1]) if out.size else command, residual_rms=0.0, ok=True,
                   motor_tau=model.motor_tau)
