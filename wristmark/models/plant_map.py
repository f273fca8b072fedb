"""The static map of an arm with a plant file's errors: from the configuration its backbones
reach (after the play) to its true configuration, frames and stem (docs/design.md "Plant file").

theta_t = g_t theta_out, delta_t = delta_out + o_t; the exposed stem (length d, incision to
{1b}) bends as a constant-curvature arc of angle zeta * theta_1 in segment 1's plane (stem
coupling); a tip force F adds to each segment's bend vector the moment of F about the
segment's base, perpendicular to its axis, divided by its stiffness (small-deflection,
evaluated on the unloaded shape). A bend (theta, delta) is the vector theta [sin d, cos d] in
the base-ring plane (the rotation axis of eq. 2), so load bends compose with commanded ones.
The simulated true arm (sim/plant.py) and the identification's fit (solvers/identification.py)
share it. Lengths [m], angles [rad], forces [N], frames in {w}.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.constant_curvature import rot_z, segment_point
from wristmark.models.kinematics import ArmFrames, forward_kinematics, tip_jacobian
from wristmark.models.plant_params import PlantParams

Array = NDArray[np.float64]
__all__ = ["true_arm", "plant_bend", "plant_tip", "plant_command"]
ANGLE_LEVER = 0.02  # [m/rad] an angle's tip lever when the inverse shares a correction among joints


def true_arm(params: Arm, plant: PlantParams) -> Arm:
    """The arm as the plant builds it: any arm's planar segments bend in their plane turned by
    the plane offset [rad]; the reference arm (flat file) as it is."""
    if not isinstance(params, ArmSpec):
        return params
    return replace(params, segments=tuple(
        replace(sg, planar=sg.planar + plant.plane_offset[t]) if sg.planar is not None else sg
        for t, sg in enumerate(params.segments)))


def _add_bend(theta: float, delta: float, dv: Array) -> tuple[float, float]:
    bx = theta * math.sin(delta) + dv[0]
    by = theta * math.cos(delta) + dv[1]
    th = math.hypot(bx, by)
    return th, (math.atan2(bx, by) if th > 0 else delta)


def _stem_bend(arm: Arm, plant: PlantParams, q: Array) -> tuple[float, float]:
    """The stem's bend (stem_coupling x theta1 [rad]) and its plane [rad] at the configuration ``q``."""
    if isinstance(arm, ArmSpec):
        de1 = arm.segments[0].planar if arm.delta_index[0] is None else float(q[arm.delta_index[0]])
        return plant.stem_coupling * float(q[arm.theta_index[0]]), de1 or 0.0
    return plant.stem_coupling * float(q[2]), float(q[3])


def _frames(arm: Arm, plant: PlantParams, q: Array) -> ArmFrames:
    """The model's chain (models.kinematics) with the stem bent by stem_coupling x theta1."""
    return forward_kinematics(arm, q, stem_bend=_stem_bend(arm, plant, q)[0])


def _stem(arm: Arm, plant: PlantParams, q: Array) -> Array:
    """Points (8, 3) along the bent stem in {w} [m], incision to {1b}."""
    theta_s, plane = _stem_bend(arm, plant, q)
    if isinstance(arm, ArmSpec):
        R_w_s, d = rot_z(float(q[arm.layout.revolute].sum())), float(q[arm.layout.prismatic].sum())
    else:
        R_w_s, d = rot_z(float(q[0])), float(q[1])
    return np.array([R_w_s @ segment_point(d, theta_s, plane, s) for s in np.linspace(0, 1, 8)])


def _load_bend(T_base: Array, tip: Array, force: Array, stiffness: float) -> Array:
    """The bend vector (2,) [rad] a tip force ``force`` [N] in {w} adds to the segment whose base
    is ``T_base`` (4x4 in {w}): its moment about the base, in the base's x-y plane, over the
    stiffness [N m/rad] (the cross product in floats: np.cross cost the fit ~40 us a call)."""
    rx, ry, rz = (tip - T_base[:3, 3]).tolist()
    fx, fy, fz = force.tolist()
    moment = np.array((ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx))
    return (T_base[:3, :2].T @ moment) / stiffness


def plant_bend(arm: Arm, plant: PlantParams, q_out: Array) -> tuple[Array, ArmFrames, Array]:
    """The true configuration, frames and stem points (8, 3) in {w} [m] of the arm ``arm``
    (:func:`true_arm`) whose backbones reach the configuration ``q_out`` [rad, m, ...]: gains,
    plane offsets, stem coupling and the tip load of ``plant`` (sized to the arm)."""
    q, frames = _bent(arm, plant, q_out)
    return q, frames, _stem(arm, plant, q)


def plant_tip(arm: Arm, plant: PlantParams, q_out: Array) -> Array:
    """The true tip in {w} [m] of :func:`plant_bend` (without its stem points)."""
    return _bent(arm, plant, q_out)[1].tip


def _bent(arm: Arm, plant: PlantParams, q_out: Array) -> tuple[Array, ArmFrames]:
    """:func:`plant_bend`'s configuration and frames: per segment the gain on theta and the
    offset on delta (a planar segment's offset is in its turned plane), then the tip load's bend
    (the reference arm's segments: (theta, delta) at (2, 3) and (4, 5))."""
    P = plant
    q = np.array(q_out, float)
    spec = arm if isinstance(arm, ArmSpec) else None
    idx: list[tuple[int, int | None]] = list(zip(spec.theta_index, spec.delta_index)) if spec else [(2, 3), (4, 5)]
    for t, (ti, di) in enumerate(idx):
        q[ti] *= P.bend_gain[t]
        if di is not None:
            q[di] += P.plane_offset[t]
    frames = _frames(arm, plant, q)
    F = np.asarray(P.tip_force, float)
    if np.any(F != 0.0):
        for t, ((ti, di), T_base) in enumerate(zip(idx, frames.segment_bases)):
            dv = _load_bend(T_base, frames.tip, F, P.segment_stiffness[t])
            if di is None:  # planar: the load's bend along the plane, theta [sin p, cos p]
                plane = (spec.segments[t].planar if spec else None) or 0.0
                q[ti] += dv[0] * math.sin(plane) + dv[1] * math.cos(plane)
            else:
                q[ti], q[di] = _add_bend(q[ti], q[di], dv)
        frames = _frames(arm, plant, q)
    return q, frames


def _gain_offset_inverse(arm: Arm, plant: PlantParams, psi: Array) -> Array:
    """The backbones' configuration whose gains and plane offsets give ``psi``'s bends."""
    q = np.array(psi, float)
    if isinstance(arm, ArmSpec):
        idx = list(zip(arm.theta_index, arm.delta_index))
    else:
        idx = [(2, 3), (4, 5)]
    for t, (ti, di) in enumerate(idx):
        q[ti] /= plant.bend_gain[t]
        if di is not None:
            q[di] -= plant.plane_offset[t]
    return q


def plant_command(arm: Arm, plant: PlantParams, psi_nominal: Array, iterations: int = 4) -> Array:
    """The backbones' configuration [rad, m, ...] at which the arm with ``plant``'s errors puts
    its tip where the nominal model puts it at ``psi_nominal`` (the identified arm's inverse, for
    the tip in {w}): the gains and plane offsets inverted exactly, then Gauss-Newton steps on the
    remaining tip error (stem coupling, load) through the nominal Jacobian, shared among the joints
    by their tip lever (angles ANGLE_LEVER [m/rad]). Not clamped to the limits."""
    target = forward_kinematics(arm, psi_nominal).tip
    arm_t = true_arm(arm, plant)
    q = _gain_offset_inverse(arm, plant, psi_nominal)
    n = q.size
    prismatic = set(arm.layout.prismatic.tolist()) if isinstance(arm, ArmSpec) else {1}
    s = np.array([1.0 if i in prismatic else 1.0 / ANGLE_LEVER for i in range(n)])
    for _ in range(iterations):
        e = target - plant_tip(arm_t, plant, q)
        if float(np.linalg.norm(e)) < 1e-8:
            break
        Js = tip_jacobian(arm, q)[:3] / s
        du = Js.T @ np.linalg.solve(Js @ Js.T + 1e-12 * np.eye(3), e)
        q = q + du / s
    return q
