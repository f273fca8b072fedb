"""Forward kinematics, the tip Jacobian and tip IK of the reference arm, through the public API.

Prints the tip and the marker pose in {w} at a configuration, checks the 6x6 Jacobian's
linear rows against central finite differences of the tip position, and solves the IK back to
a target 5 mm away. Run: ``python examples/kinematics.py [--fast]`` (it is fast either way).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from wristmark import HOME_PSI, RobotParams, forward_kinematics, solve_tip_ik, tip_jacobian, tip_position

STEP = 1e-6  # finite-difference step [rad or m]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="CI mode (the same here: everything is fast)")
    parser.parse_args()

    params = RobotParams()  # the reference arm; RobotParams.load("my_robot.yaml") for your own
    psi = np.array([0.1, 0.04, 0.7, 0.2, 0.9, -0.3])  # [rad, m, rad, rad, rad, rad]
    frames = forward_kinematics(params, psi)
    J = tip_jacobian(params, psi)  # rows 0-2: tip velocity [m/s] in {w}; rows 3-5: angular velocity [rad/s]

    # column k of the linear rows is d tip / d psi_k: compare with central differences
    fd = np.column_stack([(tip_position(params, psi + STEP * e) - tip_position(params, psi - STEP * e)) / (2 * STEP)
                          for e in np.eye(6)])
    jacobian_error = float(np.max(np.abs(fd - J[:3])))

    target = tip_position(params, HOME_PSI) + np.array([0.005, 0.0, 0.0])  # 5 mm along x_w [m]
    ik = solve_tip_ik(params, target, np.asarray(HOME_PSI, float))
    print(json.dumps({
        "psi": psi.tolist(),
        "tip_world_m": frames.tip.tolist(),
        "marker_z_world": frames.T_world_marker[:3, 2].tolist(),
        "jacobian_shape": list(J.shape),
        "jacobian_fd_max_error": jacobian_error,
        "ik_error_m": float(ik.error),
        "ik_converged": bool(ik.converged),
        "ik_tip_world_m": tip_position(params, ik.psi).tolist(),
        "ik_target_world_m": target.tolist(),
    }))


if __name__ == "__main__":
    main()
