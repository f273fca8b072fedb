"""Keep Python's garbage collector from freezing a real-time process for a tenth of a second.

CPython's cyclic collector runs when enough new container objects have been allocated; its
oldest generation then walks every tracked object of the process while holding the GIL, so
every thread stops. The host loop and the virtual lab carry large heaps of long-lived objects
(numba's and CasADi's compiled functions, scipy, OpenCV bindings, the renderer's scene), and on
this project's 2-core machine a full collection took 50-60 ms in ``wristmark servo`` and
130-145 ms in ``wristmark emulator --pty --camera-port`` (measured with ``gc.callbacks`` during
1080p virtual-lab runs): long enough, with a cycle's tracking and frame wait, to starve the
actuator box's 250 ms watchdog. :func:`freeze_heap` collects once and then moves every surviving
object to the permanent generation (:func:`gc.freeze`), which later collections skip, so they
only walk what the run itself allocates (milliseconds). Call it once, after start-up and before
the time-critical part.
"""

from __future__ import annotations

import gc
import time


def freeze_heap() -> float:
    """Collect, then exempt every object alive now from later collections; returns the time
    taken [s]. Objects allocated afterwards are collected as usual."""
    t0 = time.perf_counter()
    gc.collect()
    gc.freeze()
    return time.perf_counter() - t0
