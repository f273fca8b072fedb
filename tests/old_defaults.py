"""The controller and rig the unit tests were written against: ``ControllerConfig()`` and
``RigConfig()`` as they were before their defaults became configs/controller.yaml's and
configs/rig.yaml's (the plain qp: no dead-band inversion, tip integral or play probe, lever
0.05; delay compensation without an actuator lag, no measurement reuse). A test that builds a
loop or a controller from a few keys states them on top of these, so it tests what it always did.
"""

from __future__ import annotations

from typing import Any

from wristmark.rig.loop.rig_config import RigConfig
from wristmark.solvers.controller import ControllerConfig

# The controller keys whose default changed when the dataclass's defaults became
# configs/controller.yaml's, with their old values (configs/controller_plain.yaml's: the qp
# without dead-band inversion, tip integral or play probe).
OLD_CONTROLLER: dict[str, object] = {
    "lever": 0.05,
    "ki": 0.0,
    "integral_mode": "plain",
    "backlash_compensation": False,
    "backlash_start": 0.25,
    "backlash_fraction": 0.5,
    "backlash_lead": 0.0,
    "backlash_method": "schmitt",
    "backlash_margin": 0.02,
    "backlash_freeze": 0.0,
    "backlash_motor_burst": False,
    "backlash_kinds": ("paper", "qp"),
    "play_probe": False,
    "play_probe_learning": True,
}

# The rig keys whose default changed when the dataclass's defaults became configs/rig.yaml's.
OLD_RIG: dict[str, object] = {
    "delay_compensation_tau": 0.0,
    "reuse_measurement_age": 0.0,
    "lost_dither": 0.0,
    "reuse_lost": False,
}


def controller(**changes: Any) -> ControllerConfig:
    """The old default controller with ``changes`` (keyword arguments of ControllerConfig)."""
    return ControllerConfig(**{**OLD_CONTROLLER, **changes})  # type: ignore[arg-type]


def rig(**changes: Any) -> RigConfig:
    """The old default rig with ``changes`` (keyword arguments of RigConfig)."""
    return RigConfig(**{**OLD_RIG, **changes})  # type: ignore[arg-type]
