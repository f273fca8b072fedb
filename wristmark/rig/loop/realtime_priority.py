"""Ask the OS to schedule the calling thread in real time (Linux ``SCHED_FIFO``).

A wall-clock servo loop on a loaded host is late whenever the scheduler runs other work first:
on this project's shared 2-core machine at load ~11, cycles were up to 1.5 s late and an
actuator box's 250 ms watchdog tripped. With ``SCHED_FIFO`` the same runs kept their 60 ms
period within a few ms. It needs the right to do so (root, ``CAP_SYS_NICE`` or an ``rtprio``
limit); threads started afterwards by the same thread inherit the policy. Linux throttles
real-time threads to 95 % of a core by default, so a runaway loop cannot lock the machine.
"""

from __future__ import annotations

import os

from wristmark.models.errors import InputError

MAX_PRIORITY = 99


def request_realtime_priority(priority: int) -> None:
    """Put the calling thread (and the threads it starts from now on) under ``SCHED_FIFO`` at
    ``priority`` (1..99); InputError (one line, saying what is missing) when the OS refuses."""
    if not 1 <= int(priority) <= MAX_PRIORITY:
        raise InputError(f"real-time priority must be in 1..{MAX_PRIORITY}, got {priority}")
    if not hasattr(os, "sched_setscheduler"):
        raise InputError("real-time priority needs Linux (os.sched_setscheduler is missing here)")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
    except PermissionError:
        raise InputError(f"real-time priority {priority} refused: needs root, CAP_SYS_NICE or an rtprio limit "
                         "(e.g. 'ulimit -r 99'); run without --rt-priority otherwise") from None
    except OSError as e:
        raise InputError(f"real-time priority {priority} refused by the OS: {e.strerror or e}") from None


def check_realtime_priority(priority: int) -> None:
    """InputError unless :func:`request_realtime_priority` would succeed; leaves the calling
    thread's policy as it was (normal scheduling)."""
    request_realtime_priority(priority)
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


def realtime_priority_allowed(priority: int = 1) -> bool:
    """Whether this host lets the calling thread run under SCHED_FIFO at ``priority``."""
    try:
        check_realtime_priority(priority)
    except InputError:
        return False
    return True
