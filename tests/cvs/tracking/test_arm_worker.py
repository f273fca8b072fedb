"""An arm set with every arm but the first in a worker process (cvs.tracking.arm_worker,
``ArmSetTracker(processes=True)``): the same results as in one process, to the bit (ROI
tracking, a lost arm searched for again, a sleeve found in another arm's search and adopted, a
refit), close() ends the worker, and a killed worker is a one-line error, not a hang.

One worker process serves the module (spawning one costs ~2-3 s: imports and numba's kernels);
the last test kills it."""

from __future__ import annotations

import dataclasses
import os
import signal
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from tests.cvs.tracking.test_arm_set import CAM, HOME, SETUP, _b_at, _render
from wristmark.cvs.tracking.arm_set import ArmSetTracker, ArmWorkerError
from wristmark.cvs.tracking.arm_worker import RemoteTracker
from wristmark.cvs.tracking.result import TrackResult


@pytest.fixture(scope="module")
def remote_set() -> Iterator[ArmSetTracker]:
    """The two-arm set with arm b in a worker process (closed after the module)."""
    with ArmSetTracker(CAM, SETUP.markers, processes=True) as trk:
        yield trk


def _same(x: Any, y: Any, where: str = "") -> None:
    """``x`` and ``y`` equal to the bit, field by field (a result's times aside)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        assert type(x) is type(y), where
        for f in dataclasses.fields(x):
            if f.name not in ("time_ms", "timings"):
                _same(getattr(x, f.name), getattr(y, f.name), f"{where}.{f.name}")
    elif isinstance(x, np.ndarray):
        assert isinstance(y, np.ndarray) and x.dtype == y.dtype and x.shape == y.shape, where
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), where
    elif isinstance(x, (tuple, list)):
        assert isinstance(y, type(x)) and len(x) == len(y), where
        for i, (a, b) in enumerate(zip(x, y)):
            _same(a, b, f"{where}[{i}]")
    elif isinstance(x, dict):
        assert isinstance(y, dict) and x.keys() == y.keys(), where
        for k in x:
            _same(x[k], y[k], f"{where}[{k}]")
    elif isinstance(x, float):
        assert x == y or (np.isnan(x) and np.isnan(y)), (where, x, y)
    else:
        assert x == y, (where, x, y)


def _spy(trk: ArmSetTracker, monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, bool | None]]:
    """The calls arm b's proxy sends to its worker (a track's ``roi_only`` with it)."""
    remote = trk.trackers["b"]
    assert isinstance(remote, RemoteTracker)
    sent: list[tuple[str, bool | None]] = []
    real = remote._send

    def send(op: str, payload: Any) -> None:
        sent.append((op, payload[2] if op == "track" else None))
        real(op, payload)

    monkeypatch.setattr(remote, "_send", send)
    return sent


def test_the_worker_tracks_to_the_bit_as_one_process(remote_set: ArmSetTracker,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A short sequence through every path that reaches arm b's state: both arms searched in the
    whole frames (arm a's search finds b's sleeve: b adopts it), ROI tracking, the sleeves
    swapped (b's boxes catch a's sleeve: b reset, then b's worker searches the frames with a's
    sleeve painted out), b out of view (searched for again, then every third pair), and back."""
    remote_set.reset()
    local = ArmSetTracker(CAM, SETUP.markers, threads=False)
    sent = _spy(remote_set, monkeypatch)
    scenes = [_render([HOME, _b_at(x)], seed=k) for k, x in enumerate((0.2, 0.199))]
    scenes.append(_render([HOME, _b_at(0.2)], markers=SETUP.markers[::-1]))
    scenes += [_render([HOME, _b_at(x)], seed=k) for k, x in enumerate((0.5, 0.5, 0.5, 0.198))]
    for scene in scenes:
        want = local.track(scene.left, scene.right)
        got = remote_set.track(scene.left, scene.right)
        _same(want, got)
        assert [t.tracking for t in remote_set.trackers.values()] == [t.tracking for t in local.trackers.values()]
    assert {("adopt", None), ("track", True), ("reset", None), ("track", False)} <= set(sent), sent
    assert sum(not r.ok for r in want.values()) == 0  # b back in view, found again
    assert remote_set.stats == local.stats


def test_a_refit_in_the_worker_is_the_one_of_this_process(remote_set: ArmSetTracker) -> None:
    """refit reads the tracker's state (its start poses include the previous pose): it runs in
    the worker, and gives the local tracker's result to the bit."""
    remote_set.reset()
    local = ArmSetTracker(CAM, SETUP.markers, threads=False, clear_px=0.0)
    scene = _render([HOME, _b_at(0.2)])
    res = local.track(scene.left, scene.right)["b"]
    _same(res, remote_set.track(scene.left, scene.right)["b"])
    kl, kr = np.ones(len(res.corners_left), bool), np.ones(len(res.corners_right), bool)
    kr[np.flatnonzero(res.match.index_right >= 0)[0]] = False  # the right view has a corner to spare
    want = local.trackers["b"].refit(res, kl, kr)
    assert isinstance(want, TrackResult) and want.ok
    _same(want, remote_set.trackers["b"].refit(res, kl, kr))
    kl[:] = False
    assert remote_set.trackers["b"].refit(res, kl, kr) is None


def test_close_ends_the_worker() -> None:
    """close() (here the context manager's) asks the worker to stop: it ends at once, exit code 0,
    and the arm set tracks no more."""
    scene = _render([HOME, _b_at(0.2)])
    with ArmSetTracker(CAM, SETUP.markers, processes=True) as trk:
        remote = trk.trackers["b"]
        assert isinstance(remote, RemoteTracker)
        assert trk.track(scene.left, scene.right)["b"].ok
        t0 = time.perf_counter()
    assert remote.process.exitcode == 0 and time.perf_counter() - t0 < 2.0
    with pytest.raises(ArmWorkerError, match="arm 'b': its worker process was closed"):
        trk.track(scene.left, scene.right)
    trk.close()  # again: nothing to do


def test_a_killed_worker_is_a_clear_error_not_a_hang(remote_set: ArmSetTracker) -> None:
    """(Ends the module's worker: the module's last test.)"""
    remote = remote_set.trackers["b"]
    assert isinstance(remote, RemoteTracker) and remote.process.pid is not None
    scene = _render([HOME, _b_at(0.2)])
    remote_set.track(scene.left, scene.right)
    os.kill(remote.process.pid, signal.SIGKILL)
    remote.process.join(5.0)
    t0 = time.perf_counter()
    with pytest.raises(ArmWorkerError, match=r"^arm 'b': its worker process ended \(killed by signal 9\); build"):
        remote_set.track(scene.left, scene.right)
    assert time.perf_counter() - t0 < 2.0
    with pytest.raises(ArmWorkerError, match="killed by signal 9"):  # and every later call
        remote_set.track(scene.left, scene.right)
