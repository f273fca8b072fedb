"""A known weight on the arm's tip during the excitation (``wristmark identify --load N``): the
segments' stiffness is seen only against a known force (docs/identification.md).

:func:`with_known_load` puts the force into a plan: at every other pose on the simulated bench
(it hangs at once), or in one block, the plan's second half, on hardware, where a person hangs it.
:class:`KnownLoadPrompt` is hardware's ``apply_load``: it asks for the weight on stderr, waits for
Enter on stdin while the actuator box is fed (GET_STATE every ``poll`` s, inside its 250 ms
watchdog) and the arm held, then lets the weight settle. Forces [N] in {w}, times [s].
"""

from __future__ import annotations

import dataclasses
import select
import sys
import time
from typing import TextIO

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError
from wristmark.rig.link.actuator_link import ActuatorLink
from wristmark.rig.loop.excitation import ExcitationPlan

Array = NDArray[np.float64]
__all__ = ["GRAVITY", "KnownLoadPrompt", "load_force", "with_known_load"]

GRAVITY = 9.81  # [m/s^2]: a weight's mass from its force, for the person hanging it


def load_force(newton: float, direction: Array) -> Array:
    """The force [N] in {w} of a weight of ``newton`` pulling along ``direction`` (any length > 0)."""
    d = np.asarray(direction, float)
    norm = float(np.linalg.norm(d))
    if d.shape != (3,) or not np.all(np.isfinite(d)) or norm < 1e-9:
        raise InputError(f"the load's direction must be 3 finite numbers, not all zero: got {d.tolist()}")
    return float(newton) * d / norm


def with_known_load(plan: ExcitationPlan, force: Array, block: bool = False) -> ExcitationPlan:
    """``plan`` with ``force`` [N] in {w} hung at every other pose (``block``: at the second half's
    poses, so that a person hangs it once)."""
    n = len(plan.poses)
    on = np.arange(n) >= n // 2 if block else np.arange(n) % 2 == 1
    loads = np.where(on[:, None], np.asarray(force, float)[None, :], 0.0)
    return dataclasses.replace(plan, loads=loads)


class KnownLoadPrompt:
    """``apply_load`` for hardware: when the wanted force changes, ask the person at the bench to
    hang (or take off) the weight and wait for Enter, feeding the box meanwhile; then ``settle``
    [s] for the weight to stop swinging. A closed stdin (nobody at the keyboard) is refused in one
    line; the caller's session then holds and disables the box."""

    def __init__(self, link: ActuatorLink, ask: TextIO | None = None, tell: TextIO | None = None,
                 settle: float = 1.0, poll: float = 0.1) -> None:
        self.link = link
        self.ask = ask if ask is not None else sys.stdin
        self.tell = tell if tell is not None else sys.stderr
        self.settle = float(settle)
        self.poll = float(poll)
        self.hanging = np.zeros(3)
        self.waited_s = 0.0  # how long the arm was held for the person [s]

    def __call__(self, force: Array) -> None:
        f = np.asarray(force, float)
        if np.allclose(f, self.hanging, rtol=0.0, atol=1e-12):
            return
        t0 = time.monotonic()
        self.tell.write(self.instruction(f) + "; press Enter when it hangs still\n")
        self.tell.flush()
        self._wait_for_enter()
        until = time.monotonic() + self.settle
        while time.monotonic() < until:
            self.link.measured_actuators()
            time.sleep(min(self.poll, max(0.0, until - time.monotonic())))
        self.hanging = f
        self.waited_s += time.monotonic() - t0

    def instruction(self, force: Array) -> str:
        """What the person is asked to do for ``force`` [N] in {w}."""
        f = np.asarray(force, float)
        newton = float(np.linalg.norm(f))
        if newton == 0.0:
            return "identify: take the weight off the tip"
        d = f / newton
        return (f"identify: hang {newton:.4g} N ({1000 * newton / GRAVITY:.1f} g) on the tip, pulling along "
                f"({d[0]:.3g}, {d[1]:.3g}, {d[2]:.3g}) in {{w}}")

    def _wait_for_enter(self) -> None:
        while True:
            ready, _, _ = select.select([self.ask], [], [], self.poll)
            self.link.measured_actuators()  # a GET_STATE: the box's watchdog fed, the arm held
            if ready:
                if self.ask.readline() == "":
                    raise InputError("--load on hardware needs a person to hang the weight: stdin is closed "
                                     "(run identify in a terminal)")
                return
