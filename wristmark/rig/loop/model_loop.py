"""The servo loop on an identified arm (``--model``, docs/identification.md): its link commands
the identified arm's inverse, its motors' lag and its plays inverted (rig/link/model_link.py), so
that the controller's feed-forward and Jacobian (the nominal model's) are the identified arm's;
the controller's own dead-band inversion, which learns the plays online or from a probe that needs
a 6-DoF pose, hands over to the link's, which knows them from the identification (the reference
sleeve needs no probe)."""

from __future__ import annotations

import dataclasses

from wristmark.models.arm_spec import Arm
from wristmark.models.plant_params import PlantParams
from wristmark.rig.link.actuator_link import ActuatorLink
from wristmark.rig.link.model_link import ModelLink
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.solvers.controller import Controller

__all__ = ["MODEL_NOTE", "model_rig", "use_model"]

MODEL_NOTE = "dead-band inversion by the identified model (--model): the link inverts the identified plays and lag"


def use_model(link: ActuatorLink, params: Arm, model: PlantParams, controller: Controller | None,
              cycle: float) -> ModelLink:
    """``link`` through the identified arm ``model``'s inverse, its motors' lag (targets every
    ``cycle`` [s]) and its plays; a closed loop's ``controller`` hands its dead-band inversion over."""
    if controller is not None:
        controller.hand_over_compensation(MODEL_NOTE)
    return ModelLink(link, params, model, cycle, plays=True)


def model_rig(rig: RigConfig, model: PlantParams) -> RigConfig:
    """The rig's loop settings for the link through the identified arm ``model``, which removes
    the motors' lag (each target reached at the end of the cycle it was sent in): no feed-forward
    lead for that lag (``feedforward_lead`` 0) and a delay compensation whose model reaches each
    command one cycle after its send along the identified lag (``delay_compensation_tau`` the
    identified ``actuator_tau``, ``delay_compensation_reach`` the cycle). A frame captured after
    its cycle's start (the wall clock's phase-locked camera) is then moved back by the motion the
    arm really made, not by none."""
    return dataclasses.replace(rig, feedforward_lead=0.0, delay_compensation_tau=max(0.0, model.actuator_tau),
                               delay_compensation_reach=rig.control_dt)
