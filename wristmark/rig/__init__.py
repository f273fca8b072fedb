"""The hardware path: the servo loop, the actuator links (serial protocol v1 / v2, direct), the
driver, trajectories, run logs and metrics, the registration moves, the MJPEG server.

Frames: targets and the tip in {w} (the robot base) [m]; time on the host's clock [s].
Nothing here imports the simulated bench (``wristmark.sim``).

The names below are imported on first use (``wristmark/_lazy.py``).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.cvs.sources.mjpeg_server import MjpegServer
    from wristmark.rig.link.actuator_driver import ActuatorDriver, ActuatorError
    from wristmark.rig.link.actuator_link import ActuatorLink, DirectLink
    from wristmark.rig.link.serial_link import SerialLink, SimClock
    from wristmark.rig.loop.hardware_session import open_hardware_session
    from wristmark.rig.loop.loop_setup import LoopSetup, load_loop_setup
    from wristmark.rig.loop.metrics import ErrorStats, error_stats
    from wristmark.rig.loop.rig_config import RigConfig
    from wristmark.rig.loop.servo_loop import CameraStalledError, MarkerLostError, ServoLoop
    from wristmark.rig.loop.servo_session import LinkOptions, ServoOutcome, ServoSession, run_servo
    from wristmark.rig.loop.servo_summary import summarize as summarize_servo
    from wristmark.rig.loop.tip_sensors import TipMeasurement, TipSensor, VisionTipSensor
    from wristmark.rig.recording.run_log import CycleRecord, RunLog, read_log_csv
    from wristmark.rig.registration.poses import choose_poses
    from wristmark.rig.registration.run import Observation, collect
    from wristmark.rig.registration.run import registration_poses as registration_inputs
    from wristmark.rig.targets.trajectories import Trajectory, accuracy_targets, cube_trajectory, workspace_centre
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
