"""The registry of controller kinds: :func:`make_controller` builds the kind a configuration names.

Above the base (solvers/controller.py) and both kinds (solvers/paper_controller.py,
solvers/qp_controller.py), so the base imports neither; each kind is imported when it is built
(the ``qp`` kind imports CasADi). The kind names, ``CONTROLLER_KINDS``, stay with the
configuration they validate (``backlash_kinds``)."""

from __future__ import annotations

from wristmark.models.arm_spec import Arm
from wristmark.models.errors import ConfigError
from wristmark.solvers.controller import CONTROLLER_KINDS, Controller, ControllerConfig


def make_controller(params: Arm, config: ControllerConfig) -> Controller:
    """Build the controller ``config.kind``; an unknown kind lists the valid ones."""
    if config.kind == "paper":
        from wristmark.solvers.paper_controller import PaperController

        return PaperController(params, config)
    if config.kind == "qp":
        from wristmark.solvers.qp_controller import QpController

        return QpController(params, config)
    raise ConfigError(f"unknown controller kind {config.kind!r}; valid kinds: {', '.join(CONTROLLER_KINDS)}")
