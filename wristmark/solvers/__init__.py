"""CasADi formulations: the stereo reprojection pose solve, the controllers (``paper``, ``qp``)
and the registration solve.

Frames: the pose solve works in {ll} (the left camera), the controllers in {w} (the robot base);
units SI ([m], [rad], [s]).

The names below are imported on first use (``wristmark/_lazy.py``): ``import wristmark.solvers``
does not import CasADi.
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.solvers.controller import Controller, ControllerConfig, ControlStep, make_controller
    from wristmark.solvers.paper_controller import PaperController
    from wristmark.solvers.qp_controller import QpController
    from wristmark.solvers.registration import RegistrationPose, RegistrationResult, solve_registration, transform_error
    from wristmark.solvers.stereo_pose import MarkerPose, PoseSettings, StereoPoseSolver
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
