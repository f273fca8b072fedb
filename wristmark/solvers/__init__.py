"""The controllers (``paper``, ``qp``), the clearance between arms (their bodies as capsules, the
qp's constraint) and the registration solve (the stereo pose solve is the tracker's last stage,
in :mod:`wristmark.cvs`).

Frames: the controllers work in {w} (the robot base);
units SI ([m], [rad], [s]).

The names below are imported on first use (``wristmark/_lazy.py``): ``import wristmark.solvers``
does not import CasADi.
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.solvers.clearance import Capsules, body_capsules, clearance_rows, min_distance, transformed
    from wristmark.solvers.controller import Controller, ControllerConfig, ControlStep
    from wristmark.solvers.controller_registry import make_controller
    from wristmark.solvers.paper_controller import PaperController
    from wristmark.solvers.qp_controller import QpController
    from wristmark.solvers.registration import RegistrationPose, RegistrationResult, solve_registration, transform_error
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
