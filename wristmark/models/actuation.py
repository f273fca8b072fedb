"""Actuation map psi <-> actuator coordinates a = [phi, d, s1a, s1b, s2a, s2b] (SI).

Derivation (push-pull backbones at pitch radius r_b, docs/design.md): a backbone at angle sigma in
{tb} sits at r_b [cos sigma, sin sigma]. Our segment bends towards the direction
[cos delta, -sin delta] (paper eq. 1), so a backbone's length changes by
-r_b theta cos(sigma + delta). We define the actuator displacement s as the *pull* (shortening,
positive when the actuator retracts the backbone): s = r_b theta cos(delta + sigma). With the
two actuated backbones at sigma = 0 (x of {tb}) and sigma = +90 deg (y of {tb}):

    s_a = r_b theta cos(delta),   s_b = -r_b theta sin(delta).

This is the classic form s = r_b theta cos(delta - sigma') with the second backbone at
sigma' = -90 deg. Segment 2's backbones are taken as routed so that segment 1's bending does
not change their length (decoupled map); the simulated plant adds coupling errors on top.
Inverse: theta = hypot(s_a, s_b) / r_b, delta = atan2(-s_b, s_a).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_actuation import arm_actuator_jacobian, arm_actuators, arm_psi_from_actuators
from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.errors import InputError
from wristmark.models.kinematics import check_psi

Array = NDArray[np.float64]

ACTUATOR_NAMES = ("phi", "d", "s1a", "s1b", "s2a", "s2b")


def actuators_from_psi(params: Arm, psi: object) -> Array:
    """Actuator coordinates [rad, m, m, m, m, m] for configuration psi (any arm: models.arm_actuation)."""
    if isinstance(params, ArmSpec):
        return arm_actuators(params, check_psi(psi, params))
    q = check_psi(psi)
    a = np.empty(6)
    a[0], a[1] = q[0], q[1]
    for t in range(2):
        r, th, de = params.backbone_radius[t], q[2 + 2 * t], q[3 + 2 * t]
        a[2 + 2 * t] = r * th * math.cos(de)
        a[3 + 2 * t] = -r * th * math.sin(de)
    return a


def psi_from_actuators(params: Arm, a: object, delta_hint: object = None) -> Array:
    """Configuration psi [rad, m, rad, rad, rad, rad] from actuator coordinates [rad, m, m, m, m, m].

    At theta = 0 the bending-plane angle is undefined; it is then taken from ``delta_hint``
    (a psi whose delta entries are used), else 0.
    """
    if isinstance(params, ArmSpec):
        a1 = np.asarray(a, float)
        if a1.ndim != 1:
            raise InputError(f"actuators must have {params.m} entries, got shape {a1.shape}")
        return arm_psi_from_actuators(params, a1, delta_hint)
    x = check_psi(a)
    q = np.empty(6)
    q[0], q[1] = x[0], x[1]
    hint = check_psi(delta_hint) if delta_hint is not None else np.zeros(6)
    for t in range(2):
        r, sa, sb = params.backbone_radius[t], x[2 + 2 * t], x[3 + 2 * t]
        th = math.hypot(sa, sb) / r
        q[2 + 2 * t] = th
        q[3 + 2 * t] = math.atan2(-sb, sa) if th > 0.0 else hint[3 + 2 * t]
    return q


def actuator_jacobian(params: Arm, psi: object) -> Array:
    """6x6 d(actuators)/d(psi) at psi [rad, m, rad, rad, rad, rad]: rows follow the actuators
    [rad, m, m, m, m, m], columns follow psi."""
    if isinstance(params, ArmSpec):
        return arm_actuator_jacobian(params, check_psi(psi, params))
    q = check_psi(psi)
    J = np.eye(6)
    for t in range(2):
        r, th, de = params.backbone_radius[t], q[2 + 2 * t], q[3 + 2 * t]
        i = 2 + 2 * t
        c, s = math.cos(de), math.sin(de)
        J[i : i + 2, i : i + 2] = [[r * c, -r * th * s], [-r * s, -r * th * c]]
    return J
