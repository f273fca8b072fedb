"""Robot description: closed-form kinematics, Pinocchio model, actuation map, limits, IK, the
marker's geometry and the configuration files.

Frames (docs/conventions.md): {w} the robot base at the incision, {wm} the wrist marker, the tip
``tip_offset`` beyond {wm} along its z axis. Units SI: lengths [m], angles [rad];
psi = [phi, d, theta1, delta1, theta2, delta2] [rad, m, rad, rad, rad, rad] for the reference arm;
any arm of a format-2 robot file (``ArmSpec``, docs/your-arm.md) has the ``arm_*`` functions,
sized from the arm (n configuration variables, m actuators).

The names below are imported on first use (``wristmark/_lazy.py``).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.models.actuation import actuator_jacobian, actuators_from_psi, psi_from_actuators
    from wristmark.models.arm_actuation import arm_actuator_jacobian, arm_actuators, arm_psi_from_actuators
    from wristmark.models.arm_kinematics import ArmPoses, arm_frames, arm_tip_jacobian, arm_tip_position
    from wristmark.models.arm_pinocchio import PinocchioAnyArm
    from wristmark.models.arm_shape import ArmShape
    from wristmark.models.arm_shape import arm_shape as arm_shape_of
    from wristmark.models.arm_spec import (
        Actuation,
        Arm,
        ArmSpec,
        Segment,
        StemJoint,
        actuator_names,
        actuator_units,
        arm_names,
        arm_size,
        home_psi,
        load_arm,
    )
    from wristmark.models.arm_urdf import generate_arm_urdf
    from wristmark.models.config_files import default_config, find_config, shipped_configs
    from wristmark.models.config_io import from_mapping, load_yaml, save_yaml, to_mapping
    from wristmark.models.errors import ConfigError, InputError, LimitError, WristmarkError
    from wristmark.models.ik import IkResult, solve_tip_ik
    from wristmark.models.kinematics import ArmFrames, check_psi, forward_kinematics, tip_jacobian, tip_position
    from wristmark.models.limits import clamp_psi, clamp_velocity, psi_bounds, within_limits
    from wristmark.models.marker import MarkerCode, MarkerModel
    from wristmark.models.pinocchio_model import PinocchioArm
    from wristmark.models.robot_params import HOME_PSI, RobotParams
    from wristmark.models.urdf import generate_urdf, write_urdf
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
