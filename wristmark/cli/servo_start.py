"""What ``wristmark servo`` does before its loop runs, on one arm or on several (``--scene``): the
start configuration of a trajectory, and SIGTERM / SIGINT as Ctrl-C."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError
from wristmark.rig.targets.trajectories import Trajectory

if TYPE_CHECKING:
    from wristmark.rig.loop.loop_setup import LoopSetup

Array = NDArray[np.float64]


def start_configuration(setup: LoopSetup, traj: Trajectory) -> Array:
    """IK of the trajectory's start (raises InputError when it is out of reach)."""
    from wristmark.models.arm_spec import home_psi
    from wristmark.models.ik import solve_tip_ik

    p0 = traj.sample(0.0)[0]
    ik = solve_tip_ik(setup.params, p0, home_psi(setup.params))
    if not ik.error <= 1e-4:
        raise InputError(f"the start point {np.round(1000 * p0, 2).tolist()} mm is out of reach of the arm "
                         f"(IK misses it by {1000 * ik.error:.2f} mm)")
    return np.asarray(ik.psi, float)


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM and SIGINT stop the run like Ctrl-C (main thread only); SIGINT also when the
    process was started with it ignored (``nohup``, a background job of a script), so that
    ``kill -INT`` always holds and disables the arm."""

    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    try:
        previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGTERM, signal.SIGINT)}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
