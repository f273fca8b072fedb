"""The clearance between several arms' servo loops on one camera (docs/design.md "The virtual lab",
"Several arms"): shared by the simulated bench's lockstep loops (sim.several_arms) and the
hardware path (``wristmark servo --scene``, rig.loop.arm_set_session), so it imports nothing of
the simulated bench.

Before each cycle every arm's controller gets the other arms' bodies (capsules along their
commanded configurations, moved into its own {w}, each shifted by what vision says its tip is
off the model's: solvers.clearance) and keeps its own body ``clearance`` away from them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm
from wristmark.models.kinematics import forward_kinematics
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.solvers.clearance import DAMPER_GAIN, Capsules, body_capsules, min_distance
from wristmark.solvers.clearance import transformed as moved_capsules

Array = NDArray[np.float64]

__all__ = ["bodies_at", "least_distance", "model_bodies", "model_offsets", "set_obstacles"]


def least_distance(bodies: Mapping[str, Capsules]) -> float:
    """Least surface distance [m] between the bodies of any two arms (all in one frame)."""
    names = list(bodies)
    best = float("inf")
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            best = min(best, float(min_distance(bodies[a], bodies[b])[0]))
    return best


def model_offsets(loops: Mapping[str, ServoLoop], offsets: dict[str, Array]) -> None:
    """Update each arm's offset [m] (its {w}) of the measured tip from its model's tip at the
    commanded configuration, from its last good measurement (kept while none comes)."""
    for name, loop in loops.items():
        m = loop.last_measurement
        if loop.psi_cmd is None or m is None or not m.ok or m.p_world is None or not np.all(np.isfinite(m.p_world)):
            continue
        offsets[name] = np.asarray(m.p_world, float) - forward_kinematics(loop.params, loop.psi_cmd).tip


def bodies_at(params: Mapping[str, Arm], psi: Mapping[str, Array], bases: Mapping[str, Array],
              offsets: Mapping[str, Array] | None = None) -> dict[str, Capsules]:
    """Each arm's model body at configuration ``psi[name]`` in the scene's {w} [m] (``bases``: each
    arm's {w} in the scene's, 4x4), shifted by its tip offset ``offsets[name]`` (its {w}; none: 0)."""
    out = {}
    for name, arm in params.items():
        B = np.asarray(bases[name], float)
        T = np.eye(4)
        T[:3, 3] = B[:3, :3] @ (offsets or {}).get(name, np.zeros(3))
        out[name] = moved_capsules(body_capsules(arm, np.asarray(psi[name], float)), T @ B)
    return out


def model_bodies(bases: Mapping[str, Array], loops: Mapping[str, ServoLoop],
                 offsets: Mapping[str, Array]) -> dict[str, Capsules]:
    """Each arm's body at its commanded configuration in the scene's {w} [m], shifted by its
    vision-measured tip offset (:func:`bodies_at`)."""
    psi = {}
    for name, loop in loops.items():
        assert loop.psi_cmd is not None
        psi[name] = loop.psi_cmd
    return bodies_at({n: loop.params for n, loop in loops.items()}, psi, bases, offsets)


def set_obstacles(bases: Mapping[str, Array], loops: Mapping[str, ServoLoop], offsets: Mapping[str, Array],
                  distance: float) -> None:
    """Each arm's controller gets the other arms' bodies at their commanded configurations, moved
    into its own {w} (``bases``: each arm's {w} in the scene's, 4x4 [m]), to keep ``distance`` [m]
    from. The model is not the arm: each body is shifted by what vision says its arm's tip is off
    its model's (the other arm's offset, less this arm's own: the QP moves this arm's model body),
    so that the clearance holds between the true bodies. Both arms of a pair move at once, each
    seeing the other still: each may close only half the damper's share of the gap per cycle
    (xi / 2), so that together they close no more than one arm alone."""
    moving = sum(loop.controller is not None for loop in loops.values())
    xi = DAMPER_GAIN / 2 if moving > 1 else DAMPER_GAIN
    world = {}
    shift = {}
    for name, loop in loops.items():
        assert loop.psi_cmd is not None
        B = np.asarray(bases[name], float)
        world[name] = moved_capsules(body_capsules(loop.params, loop.psi_cmd), B)
        shift[name] = B[:3, :3] @ offsets.get(name, np.zeros(3))  # in the scene's {w}
    for name, loop in loops.items():
        if loop.controller is None:
            continue
        into = np.asarray(np.linalg.inv(bases[name]), float)  # the scene's {w} in this arm's
        others = []
        for n, c in world.items():
            if n == name:
                continue
            T = np.eye(4)
            T[:3, 3] = shift[n] - shift[name]
            others.append(moved_capsules(c, into @ T))
        loop.controller.set_obstacles(Capsules.concat(others) if others else None, distance, xi=xi)
