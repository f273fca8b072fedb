"""The controller and rig the unit tests were written against: ``ControllerConfig()`` and
``RigConfig()`` as they were before their defaults became configs/controller.yaml's and
configs/rig.yaml's (the plain qp: no dead-band inversion, tip integral or play probe, lever
0.05; delay compensation without an actuator lag, no measurement reuse). A test that builds a
loop or a controller from a few keys states them on top of these, so it tests what it always did
(the same values an old file that leaves those keys out means: tests/models/test_config_defaults.py).
"""

from __future__ import annotations

from typing import Any

from wristmark.rig.loop import rig_config
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.solvers import controller as controller_module
from wristmark.solvers.controller import ControllerConfig


def controller(**changes: Any) -> ControllerConfig:
    """The old default controller with ``changes`` (keyword arguments of ControllerConfig)."""
    return ControllerConfig(**{**controller_module.LEGACY_DEFAULTS, **changes})  # type: ignore[arg-type]


def rig(**changes: Any) -> RigConfig:
    """The old default rig with ``changes`` (keyword arguments of RigConfig)."""
    return RigConfig(**{**rig_config.LEGACY_DEFAULTS, **changes})  # type: ignore[arg-type]
