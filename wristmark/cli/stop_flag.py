"""A stop request that SIGTERM and SIGINT set from their handler without taking a lock.

A ``threading.Event`` set from a signal handler can deadlock the process: the handler runs in the
main thread between two bytecodes, and if the main thread is inside that same event's ``wait``
(which holds the event's lock around its bookkeeping), ``set`` waits forever for a lock its own
thread holds (CPython gh-126434 reports it for ``multiprocessing.Event``; ``threading.Event``
shares the cause). A lab served until SIGTERM then never stops. :class:`StopFlag` is a plain
attribute that the handler writes and the serving loop polls between sleeps."""

from __future__ import annotations

import signal
import time
from types import FrameType

__all__ = ["StopFlag", "stop_on_signals"]


class StopFlag:
    """Set once to ask a serving loop to stop; safe to set from a signal handler (no lock)."""

    def __init__(self) -> None:
        self._set = False

    def set(self) -> None:
        """Ask to stop."""
        self._set = True

    def is_set(self) -> bool:
        """Whether a stop was asked."""
        return self._set

    def wait(self, timeout: float) -> bool:
        """Sleep ``timeout`` [s] unless a stop was asked; whether one was asked (a signal that
        arrives during the sleep is seen when it ends: at most ``timeout`` late)."""
        if not self._set:
            time.sleep(timeout)
        return self._set


def stop_on_signals() -> StopFlag:
    """A :class:`StopFlag` that SIGTERM and SIGINT set (main thread only, as ``signal.signal``)."""
    flag = StopFlag()

    def _stop(signum: int, frame: FrameType | None) -> None:
        flag.set()

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    return flag
