"""Which configurations ``wristmark register`` visits: the marker in view, the workspace spanned.

Tip targets are drawn quasi-randomly (scipy's scrambled Halton sequence, seeded) in a box around
the workspace centre (the tip at HOME_PSI) and reached by the nominal tip IK; a configuration is
kept when it is within the joint limits and, when the host's calibration knows world_T_left,
the model's marker lies inside both images with its corners facing the cameras. Each pose is
approached twice, from either side (psi -/+ APPROACH; any arm: :func:`approach_offset`), so the
actuators' backlash averages out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.stats import qmc

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.marker.in_view import marker_in_view
from wristmark.models.arm_spec import Arm, ArmSpec, home_psi
from wristmark.models.errors import InputError
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics, tip_position
from wristmark.models.limits import within_limits
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]
HALF_BOX = (0.018, 0.009, 0.018)  # [m] half extent of the target box around the workspace centre (cube: 20/10/20)
APPROACH = np.array([0.02, 0.0005, 0.03, 0.05, 0.03, 0.05])  # [rad, m, rad, rad, rad, rad] approach offset


def approach_offset(params: Arm) -> Array:
    """The approach offset of each entry of psi: APPROACH for the reference arm; for any arm
    0.02 rad per revolute and 0.5 mm per prismatic stem joint, 0.03 rad per theta, 0.05 rad per
    delta (APPROACH's values for the same kinds of entry)."""
    return per_kind(params, APPROACH)


def per_kind(params: Arm, reference: Array) -> Array:
    """A value per entry of psi from the reference arm's six (phi, d, theta1, delta1, theta2,
    delta2): as they are for the reference arm; for any arm by kind, a revolute stem joint phi's,
    a prismatic one d's, each theta theta1's, each delta delta1's."""
    if not isinstance(params, ArmSpec):
        return np.asarray(reference, float)
    out = np.zeros(params.n)
    for i, j in enumerate(params.stem):
        out[i] = reference[0] if j.joint == "revolute_z" else reference[1]
    for ti, di in zip(params.theta_index, params.delta_index):
        out[ti] = reference[2]
        if di is not None:
            out[di] = reference[3]
    return out


def choose_poses(params: Arm, n: int, camera: StereoCamera | None, marker: MarkerModel,
                 seed: int = 0, half_box: tuple[float, float, float] = HALF_BOX) -> list[Array]:
    """``n`` configurations (see the module docstring); InputError when too few qualify."""
    if n < 1:
        raise InputError(f"--poses must be >= 1, got {n}")
    centre = tip_position(params, home_psi(params))
    draws = qmc.Halton(d=3, scramble=True, seed=seed).random(max(64, 8 * n))
    W_inv = None if camera is None or camera.T_world_left is None else np.linalg.inv(camera.T_world_left)
    out: list[Array] = []
    home = home_psi(params)
    step = approach_offset(params)
    for u in draws:
        target = centre + (2.0 * u - 1.0) * np.asarray(half_box)
        ik = solve_tip_ik(params, target, home)
        q = np.asarray(ik.psi, float)
        if not ik.converged or not within_limits(params, q):
            continue
        if not (within_limits(params, q - step) and within_limits(params, q + step)):
            continue
        if W_inv is not None and camera is not None:
            T_lm = W_inv @ forward_kinematics(params, q).T_world_marker
            if not marker_in_view(camera, marker, T_lm, min_corners=4, margin_px=0.06 * camera.image_size[1]):
                continue
        out.append(q)
        if len(out) == n:
            return out
    raise InputError(f"only {len(out)} of {n} poses keep the marker in view: check the calibration's "
                     "world_T_left, or ask for fewer --poses")
