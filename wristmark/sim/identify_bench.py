"""The identification's excitation on the simulated bench: a fresh true arm of the setup's
plant file, its rendered frames tracked (vision, the default; or the rig's truth-noise option),
moved through an excitation plan (rig/loop/excitation.py) and fitted (solvers/identification.py)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.loop.excitation import ExcitationPlan, excitation_plan, run_excitation
from wristmark.rig.loop.known_load import load_force, with_known_load
from wristmark.sim.setup import SimSetup, make_measurement, make_plant
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.identification import ExcitationData

__all__ = ["bench_plan", "excite_on_bench"]


def bench_plan(setup: SimSetup, poses: int = 30, seed: int | None = None, load: float = 0.0,
               direction: tuple[float, float, float] = (0.0, 0.0, -1.0)) -> ExcitationPlan:
    """The default excitation for the setup's arm: plays in units of the controller's
    backlash_play_max (sized to the arm); ``load`` > 0 [N]: a known weight (pulling along
    ``direction`` in {w}, default -z_w) hung on the tip at every other pose (the segments'
    stiffness is then seen)."""
    unit = ControllerConfig.play_max_for(setup.controller, setup.params)
    plan = excitation_plan(setup.params, unit, poses=poses, seed=setup.rig.seed if seed is None else seed)
    if load <= 0:
        return plan
    return with_known_load(plan, load_force(load, np.asarray(direction, float)))


def excite_on_bench(setup: SimSetup, plan: ExcitationPlan, seed: int | None = None,
                    on_pose: Callable[[int], None] | None = None) -> ExcitationData:
    """Run ``plan`` on a fresh simulated true arm (started at the plan's first pose) with the
    rig's sensor; the record for the fit."""
    seed = setup.rig.seed if seed is None else seed
    plant = make_plant(setup, plan.poses[0])
    link = DirectLink(plant)
    frames, sensor = make_measurement(setup, plant, lambda: link.time, seed)
    own = plant.plant

    def hang(force: np.ndarray) -> None:  # the known load on top of the arm's own
        f = np.asarray(own.tip_force, float) + np.asarray(force, float)
        plant.plant = dataclasses.replace(own, tip_force=(float(f[0]), float(f[1]), float(f[2])))

    return run_excitation(setup.params, link, frames, sensor, plan, setup.rig.control_dt, on_pose=on_pose,
                          apply_load=hang if plan.loads is not None else None)
