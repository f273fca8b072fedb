"""Several coded sleeves of one family in one stereo pair, each its own arm: :class:`ArmSetTracker`.

Each arm has its own :class:`MarkerTracker` (ROI tracking per arm). Per pair, first every arm
that was tracked is searched in its own boxes only (``roi_only``; the arms side by side in
worker threads, or with ``processes=True`` every arm but the first in a worker process of its
own: cvs.tracking.arm_worker; each result's gate at its corners' contrast noise is computed
while the others are searched, and used where clearing leaves the result as it was); then
the arms still missing are searched in whole frames in which the sleeves already found in this
pair are painted out (the search finds one chain, the longest: a second
sleeve is found only once the first is gone); an arm missing from pair to pair is searched for
again in the next pair, then in every ``search_every``-th pair only (a whole-frame search costs
several ROI searches). A pose counts for an arm only when the sleeve's code says it is that arm (``res.code.arm``): a
chain that an arm's boxes caught on another arm's sleeve (crossing, touching), or a sleeve
whose code cannot be decided (too few code cells seen), is no arm's. So identities never swap:
a sleeve is reported as an arm only on its own code, and the code's single-error margin holds
across the family (cvs.marker.family).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.gray_image import check_view
from wristmark.cvs.tracking.arm_worker import (
    CALL_TIMEOUT_S,
    ArmWorkerError,
    PendingTrack,
    RemoteTracker,
    SharedFrames,
    start_remote_trackers,
)
from wristmark.cvs.tracking.neighbour_corners import outlines, reached
from wristmark.cvs.tracking.result import Array, TrackResult
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel, check_marker_set

Box = tuple[int, int, int, int]  # (u0, v0, u1, v1) [px], end exclusive
_SEARCHING = "not in view (searched for in the whole frames meanwhile)"  # an arm a background search looks for

__all__ = ["ArmSetTracker", "ArmWorkerError", "core_to_spare", "identity", "sleeve_boxes"]


def core_to_spare() -> bool:
    """Whether the machine's load (1-minute average, this process included) is below its cores
    plus one. Above it the arms' threads only wait for each other and for the cores: two arms on
    2 cores took 17.4 / 20.1 ms a pair in threads against 16.3 / 18.8 ms in one at load ~5 / ~7
    (medians of 200 pairs, interleaved; docs/notes/several-arms.md "Time"); at load 1-2 the
    threads cut the time by ~25 %."""
    try:
        return os.getloadavg()[0] < (os.cpu_count() or 1) + 1
    except OSError:  # no load average on this system
        return True


def identity(res: TrackResult) -> str | None:
    """The arm a result's sleeve is, by its code (None: no pose, or the code did not decide it)."""
    if res.ok and res.roll_known and res.code is not None and res.code.ok:
        return res.code.arm
    return None


def sleeve_boxes(camera: StereoCamera, marker: MarkerModel, T_left_marker: Array, margin_px: float = 6.0
                 ) -> tuple[Box | None, Box | None]:
    """Pixel boxes (u0, v0, u1, v1) of the whole sleeve (every side, code bands included) in the
    left and right images for a pose of {wm} in {ll} [m]; None where it is behind a camera."""
    ang = np.linspace(0.0, 2.0 * np.pi, 25)
    z_lo, z_hi = marker.z_extent
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)]) * marker.radius
    pts = np.vstack([ring + [0.0, 0.0, z] for z in np.linspace(z_lo, z_hi, 3)])
    P_left = pts @ T_left_marker[:3, :3].T + T_left_marker[:3, 3]
    P_right = P_left @ np.asarray(camera.R, float).T + np.asarray(camera.T, float).reshape(3)
    w, h = camera.image_size
    out: list[Box | None] = []
    for cam, P in ((camera.left, P_left), (camera.right, P_right)):
        if np.any(P[:, 2] <= 1e-3):
            out.append(None)
            continue
        uv = cam.project(P)
        lo, hi = uv.min(axis=0) - margin_px, uv.max(axis=0) + margin_px
        box = (max(0, int(np.floor(lo[0]))), max(0, int(np.floor(lo[1]))),
               min(w, int(np.ceil(hi[0])) + 1), min(h, int(np.ceil(hi[1])) + 1))
        out.append(box if box[0] < box[2] and box[1] < box[3] else None)
    return out[0], out[1]


def _given(res: TrackResult) -> TrackResult:
    return res


def _paint_out(img: NDArray[np.uint8], box: Box | None) -> None:
    """Fill ``box`` of ``img`` (in place) with the mean of its border: no edge crosses it."""
    if box is None:
        return
    u0, v0, u1, v1 = box
    patch = img[v0:v1, u0:u1]
    border = np.concatenate([patch[0].reshape(-1, *img.shape[2:]), patch[-1].reshape(-1, *img.shape[2:]),
                             patch[:, 0].reshape(-1, *img.shape[2:]), patch[:, -1].reshape(-1, *img.shape[2:])])
    patch[...] = np.asarray(border.mean(axis=0), np.float64).round().astype(np.uint8)


class ArmSetTracker:
    """Stereo tracker of a set of coded sleeves (one marker file per arm, each naming its arm,
    codes of one family: models.marker.check_marker_set). Poses in {ll} [m] per arm."""

    def __init__(self, camera: StereoCamera, markers: Sequence[MarkerModel],
                 settings: TrackerSettings | None = None, names: Sequence[str] | None = None,
                 threads: bool = True, search_every: int = 3, clear_px: float = 6.0, body_lengths: float = 1.0,
                 edge_ratio: float = 0.3, max_sigma_ratio: float = 1.6, contrast_noise: float | None = None,
                 max_tip_sigma_m: float | None = None, processes: bool = False,
                 worker_timeout_s: float = CALL_TIMEOUT_S, background_search: bool = False) -> None:
        """``names``: the marker files' names for the messages (default the arms'); ``threads``:
        the arms' ROI searches run side by side in worker threads while the machine has a core to
        spare (:func:`core_to_spare`; results are the same either way); ``processes``: every arm
        but the first is tracked in a worker process of its own instead (cvs.tracking.arm_worker:
        started here, ~2-3 s, waited for; reused until :meth:`close`; the same results to the bit;
        ``threads`` then unused), a worker that ends or does not answer within
        ``worker_timeout_s`` [s] raising ``ArmWorkerError``;
        ``search_every``: an arm missing from pair to pair is searched for in the whole frames in
        every so many pairs (1: every pair); ``background_search``: where another arm was found in
        its boxes in the pair, that search runs in a thread of its own while the next pairs are
        tracked (the arms found in their boxes are returned without waiting for it; what it finds
        is adopted at the first pair after it ends, and tracked in its boxes from that pair on),
        where every missing arm is tracked in this process (for a real-time loop: a lost arm's
        search held every other arm's cycle for up to the tracking budget;
        docs/notes/several-arms.md); ``contrast_noise`` [px x grey levels],
        ``max_tip_sigma_m`` [m]: the gate on each arm's tip sigma at its corners' contrast noise
        (MarkerTracker.contrast_gate, after clearing; default the settings'
        ``gate_contrast_noise`` and ``max_contrast_tip_sigma_m``). With several arms the trackers
        solve from the corners alone (``edge_sigma_px`` 0: another sleeve can stand in a bar's
        search, cvs.tracking.print_edges; docs/notes/print-bars.md)."""
        if int(search_every) < 1:
            raise InputError(f"search_every must be >= 1, got {search_every}")
        markers = list(markers)
        if not markers:
            raise InputError("an arm set needs at least one marker")
        if len(markers) == 1 and markers[0].arm is None:
            raise InputError("an arm set's marker must name its arm ('arm: NAME' in the marker file)")
        check_marker_set(markers, list(names) if names is not None else [str(m.arm) for m in markers])
        self.camera = camera
        self.markers = {str(m.arm): m for m in markers}
        self.arms = list(self.markers)
        self.trackers: dict[str, MarkerTracker | RemoteTracker] = {}
        self._frames: SharedFrames | None = None
        if len(markers) > 1:  # corners only: another sleeve's edges can stand in a bar's search (print_edges)
            settings = replace(settings if settings is not None else TrackerSettings(), edge_sigma_px=0.0)
        self.settings = settings if settings is not None else TrackerSettings()  # every arm's tracker's
        if processes and len(markers) > 1:
            self._frames, remotes = start_remote_trackers(camera, markers[1:], settings, markers, worker_timeout_s)
            self.trackers = {self.arms[0]: MarkerTracker(camera, markers[0], settings, family=markers)}
            self.trackers.update(zip(self.arms[1:], remotes))
        else:
            self.trackers = {a: MarkerTracker(camera, m, settings, family=markers) for a, m in self.markers.items()}
        self.search_every = int(search_every)
        self.clear_px, self.body_lengths, self.edge_ratio = float(clear_px), float(body_lengths), float(edge_ratio)
        self.max_sigma_ratio = float(max_sigma_ratio)
        self.contrast_noise, self.max_tip_sigma_m = contrast_noise, max_tip_sigma_m
        self.stats = {"cleared": 0, "refit": 0, "kept": 0, "searches": 0}  # searches: whole-frame
        self._missing_last: set[str] = set()
        self._pairs_missing = 0
        self.retired: frozenset[str] = frozenset()  # arms no longer tracked (:meth:`retire`)
        # the arms' ROI searches side by side (OpenCV, numba and the solver release the GIL)
        self._pool = ThreadPoolExecutor(max_workers=len(markers) - 1, thread_name_prefix="arm-set") \
            if threads and len(markers) > 1 and self._frames is None else None
        self._search_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="arm-set-search") \
            if background_search and len(markers) > 1 else None
        self._search: Future[tuple[dict[str, TrackResult], list[str]]] | None = None
        self._searching: frozenset[str] = frozenset()  # the arms a background search is looking for

    def close(self) -> None:
        """Stop the worker processes (``processes``) and threads; idempotent. The arm set tracks
        no more pairs after it (a worker's arm would raise ArmWorkerError)."""
        if self._search_pool is not None:
            self._search_pool.shutdown(wait=True)
        for t in self.trackers.values():
            if isinstance(t, RemoteTracker):
                t.close()
        if self._frames is not None:
            self._frames.close()
        if self._pool is not None:
            self._pool.shutdown(wait=True)

    def __enter__(self) -> ArmSetTracker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def retire(self, arm: str) -> None:
        """Track arm ``arm`` no more (its loop has stopped: held and disabled): neither in its
        boxes nor by the whole-frame search, which would otherwise go on every ``search_every``-th
        pair for a sleeve nobody waits for, at several times an ROI search's cost taken from the
        other arms' cycles. Its result is then ``ok=False`` ("retired"). Its sleeve, if in view,
        is still never read as another arm's: the other arms' results keep their identity checks."""
        if arm not in self.markers:
            raise KeyError(f"no arm '{arm}' in the marker set ({', '.join(self.arms)})")
        self._collect_search(wait=True)  # its tracker is then the caller's alone
        self.trackers[arm].reset()
        self.retired = self.retired | {arm}  # a new set: a tracking thread reads the old one whole

    def reset(self) -> None:
        """Forget every arm's ROI state (the next pair searches the whole frames for every arm)."""
        self._collect_search(wait=True)
        for t in self.trackers.values():
            t.reset()
        self._missing_last, self._pairs_missing = set(), 0

    def track(self, left_img: Any, right_img: Any,
              axis_hints_left: Mapping[str, Array] | None = None) -> dict[str, TrackResult]:
        """Track every arm's sleeve in one stereo pair (uint8 grey or BGR of the calibrated size):
        one result per arm, in the order of the markers. An arm whose sleeve is not found, or is
        found but not decided by its code, is ``ok=False`` with the reason. ``axis_hints_left``:
        per arm, the expected direction of its z_wm in {ll} (used only before the code decides)."""
        il = check_view(left_img, self.camera.image_size, "left")
        ir = check_view(right_img, self.camera.image_size, "right")
        hints = dict(axis_hints_left or {})
        retired = self.retired
        results: dict[str, TrackResult] = {a: self._missing("retired: its loop has stopped") for a in retired}
        found: list[TrackResult] = []
        self._collect_search()
        searching = self._searching  # their trackers are the background search's until it ends
        tracked = [a for a in self.arms if a not in retired and a not in searching and self.trackers[a].tracking]
        jobs = self._start_rois(tracked, il, ir, hints)
        early: dict[str, tuple[TrackResult, Callable[[], TrackResult]]] = {}  # gates of phase one's results
        for arm in tracked:  # each arm that was tracked, in its own boxes only (one per thread or process)
            trk = self.trackers[arm]
            job = jobs.get(arm)
            res = job.result() if job is not None else trk.track(il, ir, axis_hint_left=hints.get(arm), roi_only=True,
                                                                 contrast_gate=False)
            who = identity(res)
            if who == arm:
                results[arm] = res
                found.append(res)
                if isinstance(job, PendingTrack):  # gated in the worker meanwhile
                    early[arm] = (res, job.gated)
                elif job is None and jobs:  # gated now, while the other arms' searches run elsewhere
                    early[arm] = (res, partial(_given, trk.contrast_gate(res, (il, ir), self.contrast_noise,
                                                                         self.max_tip_sigma_m)))
            else:  # lost, or its boxes caught another sleeve: searched again below
                trk.reset()
        pending = [a for a in self.arms if a not in results]
        if searching:  # an arm lost in its boxes now is searched for once that search has ended
            return self._reported(results, {a: _SEARCHING if a in searching else "lost in its boxes (the whole frames "
                                            "are being searched for another arm)" for a in pending}, (il, ir), early)
        # arms missing in the last pair too (after one more search: a sleeve lost for one pair is
        # usually found in the next) are searched for in every ``search_every``-th pair only (a
        # whole-frame search per missing sleeve costs several times an ROI search)
        still = bool(pending) and set(pending) <= self._missing_last
        self._pairs_missing = self._pairs_missing + 1 if still else 0
        if still and self._pairs_missing > 1 and self._pairs_missing % self.search_every:
            return self._reported(results, dict.fromkeys(pending, f"not in view (searched for every "
                                                                   f"{self.search_every} pairs)"), (il, ir), early)
        self._missing_last = set(pending)  # what the whole-frame search below does not find stays missing
        if self._search_pool is not None and found and all(isinstance(self.trackers[a], MarkerTracker)
                                                           for a in pending):  # only while others are tracked
            self._searching = frozenset(pending)
            self._search = self._search_pool.submit(self._search_whole, il.copy(), ir.copy(), list(found),
                                                    list(pending), hints, True)
            return self._reported(results, dict.fromkeys(pending, _SEARCHING), (il, ir), early)
        got, failures = self._search_whole(il, ir, found, pending, hints, False)
        results.update(got)
        pending = [a for a in pending if a not in got]
        self._missing_last = set(pending)
        why = "not found; " + "; ".join(failures) if failures else "not in view"
        return self._reported(results, dict.fromkeys(pending, why), (il, ir), early)

    def _reported(self, results: dict[str, TrackResult], missing: Mapping[str, str], images: tuple[Any, Any],
                  early: Mapping[str, tuple[TrackResult, Callable[[], TrackResult]]]) -> dict[str, TrackResult]:
        """Every arm's result of the pair, in the markers' order: its own (:meth:`_own`) where
        ``results`` has one, else not found for the reason ``missing`` gives; cleared of other
        arms' edges (:meth:`_clear`) and gated (:meth:`_gated`)."""
        own = {a: self._own(a, results[a]) if a in results else self._missing(missing[a]) for a in self.arms}
        return self._gated(self._clear(own, images), images, early)

    def finish_search(self) -> None:
        """Wait for a background search (``background_search``) to end and let each arm it found
        adopt its result; nothing when none runs."""
        self._collect_search(wait=True)

    def _collect_search(self, wait: bool = False) -> None:
        """A background search that has ended (``wait``: once it ends): each arm it found adopts
        its result (tracked in its boxes from the next pair on), unless retired meanwhile; its
        error, if it raised one, raised here."""
        job = self._search
        if job is None or not (wait or job.done()):
            return
        self._search = None
        try:
            got, _ = job.result()
        finally:
            self._searching = frozenset()
        for arm, res in got.items():
            if arm not in self.retired:
                self.trackers[arm].adopt(res)

    def _search_whole(self, il: NDArray[np.uint8], ir: NDArray[np.uint8], found: list[TrackResult],
                      pending: list[str], hints: Mapping[str, Array],
                      background: bool) -> tuple[dict[str, TrackResult], list[str]]:
        """The arms ``pending`` searched for in whole frames with the sleeves ``found`` (and each
        found here) painted out, one search per sleeve: the results of the arms found (each
        identified by its code) and why the others were not. Adopted at once by its arm's tracker,
        or (``background``: in the search's thread, which uses only the pending arms' trackers)
        left for :meth:`_collect_search`, every searcher reset."""
        pending = list(pending)
        results: dict[str, TrackResult] = {}
        found = list(found)
        masked: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None = None
        failures: list[str] = []
        hidden: list[tuple[int, Box]] = []  # one view's chain of two sleeves, hidden until a sleeve is found
        for _ in range(2 * len(self.arms) + 2):  # each search finds one sleeve (or none: done)
            if not pending:
                break
            if masked is None:
                masked = (il.copy(), ir.copy())
                for r in found:
                    self._paint(masked, r)
                for v, box in hidden:
                    _paint_out(masked[v], box)
            searcher = self.trackers[pending[0]]
            searcher.reset()
            self.stats["searches"] += 1
            res = searcher.track(masked[0], masked[1], axis_hint_left=hints.get(pending[0]), contrast_gate=False)
            if len(hidden) < 2 and (chain := self._two_sleeves(res, len(hidden) % 2)) is not None:
                # each view's chain on another sleeve: painting both out would lose both sleeves
                hidden.append(chain)
                masked = None
                continue
            if not self._paint(masked, res):
                break  # nothing more in view
            found.append(res)  # painted out of a rebuilt mask too
            if hidden and res.T_left_marker is not None:  # a sleeve found: the hidden chain's back
                hidden, masked = [], None
            who = identity(res)
            if who in pending:
                if background:
                    searcher.reset()  # the arm's tracker adopts it in the caller's thread
                elif self.trackers[who] is not searcher:
                    searcher.reset()
                    self.trackers[who].adopt(res)
                results[who] = res
                pending.remove(who)
                continue
            searcher.reset()
            if res.ok and who is None:
                why = res.code.reason if res.code is not None else "no code"
                failures.append(f"a sleeve in view not identified ({why})")
            elif res.ok:
                failures.append(f"a second sleeve read as arm '{who}'")
            else:
                failures.append(f"a sleeve in view not tracked ({res.reason})")
        return results, failures

    def _start_rois(self, tracked: list[str], il: NDArray[np.uint8], ir: NDArray[np.uint8],
                    hints: Mapping[str, Array]) -> dict[str, Any]:
        """Phase one's ROI searches started elsewhere (each with ``.result()``): every tracked arm
        of a worker process (the pair copied once into the buffer they share), or every tracked
        arm but the first in threads while a core is to spare; the others run in this thread."""
        remote = {a: t for a in tracked if isinstance(t := self.trackers[a], RemoteTracker)}
        if remote and self._frames is not None:
            shapes = self._frames.put(il, ir)
            after = (self.contrast_noise, self.max_tip_sigma_m)
            return {a: t.submit(shapes, hints.get(a), True, False, after) for a, t in remote.items()}
        if self._pool is not None and len(tracked) > 1 and core_to_spare():
            return {a: self._pool.submit(self.trackers[a].track, il, ir, hints.get(a), True, False)
                    for a in tracked[1:]}
        return {}

    def _clear(self, results: dict[str, TrackResult], images: tuple[Any, Any]) -> dict[str, TrackResult]:
        """Each arm's pose solved again without its corners another arm's edges may reach (a
        corner's sub-pixel fit takes in what its window holds, and a neighbour's edge pulls it off
        by less than the pose solve's outlier test sees): a corner within ``clear_px`` of the
        outline of an arm found in this pair that is nearer the camera (its sleeve, the tool out
        to the tip and ``body_lengths`` sleeve lengths of body behind it), or whose window
        (``clear_px``) holds an edge outside this arm's own outline (a sleeve behind it that is not
        found, or found: cvs.tracking.neighbour_corners). A result whose refit fails a gate (too few corners
        left) stays as it was. Not with one arm: an arm set of one is the one-arm tracker."""
        poses = {a: r.T_left_marker for a, r in results.items() if r.ok and r.T_left_marker is not None}
        good = [a for a in self.arms if a in poses]
        if not good or len(self.arms) < 2 or self.clear_px <= 0:
            return results
        marker = self.markers[good[0]]
        z_lo, z_hi = marker.z_extent
        z_back, z_tip = z_lo - self.body_lengths * (z_hi - z_lo), max(z_hi, float(marker.tip()[2]))
        bodies = outlines(self.camera, marker, poses, z_back, z_tip)
        out = dict(results)
        for a in good:
            res = results[a]
            keep = []
            for v, corners in enumerate((res.corners_left, res.corners_right)):
                own = bodies[a][v]
                others = [o for b in good if b != a and (o := bodies[b][v]) is not None]
                keep.append(np.ones(len(corners), bool) if own is None else
                            ~reached(images[v], corners, own, others, self.clear_px, self.edge_ratio))
            if all(k.all() for k in keep):
                continue
            self.stats["cleared"] += 1
            refit = self.trackers[a].refit(res, keep[0], keep[1], self.max_sigma_ratio)
            if refit is not None:
                out[a] = refit
                self.stats["refit"] += 1
            else:
                self.stats["kept"] += 1
        return out

    def _gated(self, results: dict[str, TrackResult], images: tuple[Any, Any],
               early: Mapping[str, tuple[TrackResult, Callable[[], TrackResult]]]) -> dict[str, TrackResult]:
        """Each good result through its tracker's gate on the tip sigma at the corners' contrast
        noise and residuals (MarkerTracker.contrast_gate; after clearing, on the corners the pose
        uses): a small, dark sleeve near the image's edge has 3-4 corners a view of 0.25-0.35 px
        noise (three arms seed 2, sequence 8, arm c, 4 + 4 corners, 0.72 mm off at 0.19 mm of sigma
        at 0.1 px, 0.56 mm at their contrast; docs/notes/several-arms.md). ``early``: per arm, a
        result of phase one and its gate, computed while other arms were searched (a function of
        the result and the images only): used where clearing left that result as it was."""
        return {a: early[a][1]() if a in early and early[a][0] is r else
                self.trackers[a].contrast_gate(r, images, self.contrast_noise, self.max_tip_sigma_m)
                for a, r in results.items()}

    def _own(self, arm: str, res: TrackResult) -> TrackResult:
        """``res`` as arm ``arm``'s result: a pose only when its code says it is that arm."""
        if res.ok and identity(res) != arm:
            return replace(res, ok=False, reason="sleeve in view not identified as this arm")
        if not res.ok and not res.reason:
            return replace(res, reason="not in view")
        return res

    def _missing(self, reason: str) -> TrackResult:
        empty = np.zeros((0, 2))
        return TrackResult(False, reason, None, None, None, empty, empty, float("nan"), 0.0, {})

    def _two_sleeves(self, res: TrackResult, view: int) -> tuple[int, Box] | None:
        """Where a whole-frame search chained a different sleeve in each view (enough corners in
        both, no stereo pairs between them): the box of ``view``'s chain, to hide from the next
        search so that both views chain the same sleeve (bench/several_arms.py three arms seed
        3, sequence 9: arm a lost for 6 pairs in a row); None otherwise."""
        n = self.trackers[self.arms[0]].settings
        m = res.match
        if res.ok or res.pose is not None or m is None or m.n_pairs >= n.min_pairs:
            return None
        chains = (res.corners_left, res.corners_right)
        if min(len(chains[0]), len(chains[1])) < n.min_corners:
            return None
        c = chains[view]
        gap = float(np.median(np.hypot(*np.diff(c, axis=0).T)))
        lo, hi = c.min(axis=0) - gap, c.max(axis=0) + gap
        w, h = self.camera.image_size
        return view, (max(0, int(lo[0])), max(0, int(lo[1])), min(w, int(hi[0]) + 1), min(h, int(hi[1]) + 1))

    def _paint(self, images: tuple[NDArray[np.uint8], NDArray[np.uint8]], res: TrackResult) -> bool:
        """Paint a result's sleeve out of both (copied) images: the whole sleeve where a pose was
        fitted, else the box of its corners grown by two spacings; False when it has neither."""
        if res.T_left_marker is not None:
            marker = next(iter(self.markers.values()))
            for img, box in zip(images, sleeve_boxes(self.camera, marker, res.T_left_marker)):
                _paint_out(img, box)
            return True
        painted = False
        for img, c in zip(images, (res.corners_left, res.corners_right)):
            if c is None or len(c) < 2:
                continue
            gap = float(np.median(np.hypot(*np.diff(c, axis=0).T)))
            lo, hi = c.min(axis=0) - 2.0 * gap, c.max(axis=0) + 2.0 * gap
            h, w = img.shape[:2]
            _paint_out(img, (max(0, int(lo[0])), max(0, int(lo[1])), min(w, int(hi[0]) + 1), min(h, int(hi[1]) + 1)))
            painted = True
        return painted
