"""wristmark: closed-loop control of a continuum surgical manipulator from stereo-endoscope
tracking of a marker on its wrist.

The most used names are here (``from wristmark import MarkerTracker, forward_kinematics``); each
subpackage has the rest of its public API in its own ``__all__``. Subpackages, lowest first (each
imports only those before it): ``models`` (kinematics, robot parameters, the marker, limits,
configuration files), ``cvs`` (cameras, calibration, the marker tracker, frame sources),
``solvers`` (the stereo pose solve, the controllers), ``rig`` (the servo loop, the actuator
links), ``viz`` (the Meshcat views), ``sim`` (the simulated bench: true plant, renderer,
emulator, experiments) and ``cli`` (the command line).

Frames and units (docs/conventions.md): {w} the robot base at the incision, {ll} the left
camera, {wm} the wrist marker; SI units ([m], [rad], [s]). Every name is imported on first use
(``wristmark/_lazy.py``): ``import wristmark`` imports neither OpenCV, CasADi, Meshcat, dask nor
the simulated bench.
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

__version__ = "0.1.0"

if TYPE_CHECKING:
    from wristmark.cvs import (
        MarkerTracker,
        SourceOptions,
        StereoCamera,
        StereoFrame,
        StereoSource,
        TrackResult,
        load_calibration,
        load_registration,
        open_stereo_source,
        save_calibration,
        warm_up,
    )
    from wristmark.models import (
        HOME_PSI,
        MarkerModel,
        RobotParams,
        WristmarkError,
        forward_kinematics,
        solve_tip_ik,
        tip_jacobian,
        tip_position,
    )
    from wristmark.rig import (
        ActuatorLink,
        DirectLink,
        LoopSetup,
        SerialLink,
        ServoLoop,
        load_loop_setup,
        open_hardware_session,
        run_servo,
    )
    from wristmark.solvers import Controller, ControllerConfig, make_controller
    from wristmark.viz import LiveView, start_live_view
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__, extra=("__version__",))
