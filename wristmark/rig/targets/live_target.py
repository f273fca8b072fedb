"""Live targets: the tip steered by a stream of poses from another program (a surgeon's input
device, a script, a ROS 2 node) instead of a built-in trajectory.

A target is a tip position ``p`` in {w} [m] and optionally the tip frame's orientation ``q``
(unit quaternion x, y, z, w of the rotation mapping the tip frame's axes into {w}), stamped with
the sender's time ``t`` [s]. Sources: ``stdin`` and ``tcp:127.0.0.1:PORT`` take JSON lines
``{"t": s, "p": [x, y, z], "q": [qx, qy, qz, qw]}`` (``q`` optional); the ROS 2 source
(rig/ros2/) feeds the same store.

Safety, whatever the sender does:

* the loop follows the newest target only, moved towards at most ``max_speed`` [m/s] (and
  ``max_angular_speed`` [rad/s] for the orientation) on the loop's clock;
* a target outside the workspace box is clamped onto it (counted as ``clamped``);
* a stream silent for longer than ``timeout`` [s] (host's monotonic clock) holds the arm where its
  target stands (each hold counted; a fresh target resumes);
* a malformed message (not JSON, not an object, missing or non-finite numbers, a zero-norm
  quaternion, a time older than the newest accepted) is counted as ``dropped`` with a warning line
  on stderr (the first MAX_WARNINGS of them) and never moves the arm.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import select
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.models.errors import InputError
from wristmark.rig.targets.orientation_path import OrientationPath
from wristmark.rig.targets.trajectories import CUBE_SIZE, Trajectory

Array = NDArray[np.float64]
LIVE_DURATION_S = 60.0  # [s] default run time with live targets
TARGET_TIMEOUT_S = 0.2  # [s] a target stream silent for longer holds the arm
MAX_SPEED = 0.02  # [m/s] default bound of the target's speed (the paper's cube runs at 10 mm/s)
MAX_ANGULAR_SPEED = 0.5  # [rad/s] default bound of the target orientation's turn rate
WORKSPACE_MARGIN = 0.005  # [m] the default workspace: the cube's box grown by this on every side
MAX_LINE = 65536  # [bytes] a longer line is malformed
MAX_WARNINGS = 10  # warning lines on stderr; later drops are only counted
LIVE_KINDS = ("stdin", "tcp", "ros2")
LOOPBACK_HOSTS = ("127.0.0.1", "localhost")


@dataclass(frozen=True)
class Workspace:
    """An axis-aligned box in {w}: ``centre`` (3,) and ``half`` extents (3,) [m]."""

    centre: Array
    half: Array

    @classmethod
    def around(cls, centre: Array, size: tuple[float, float, float] = CUBE_SIZE,
               margin: float = WORKSPACE_MARGIN) -> Workspace:
        """The box of edges ``size`` [m] around ``centre``, grown by ``margin`` [m] on every side."""
        return cls(np.asarray(centre, float).copy(), 0.5 * np.asarray(size, float) + margin)

    def clamp(self, p: Array) -> tuple[Array, bool]:
        """``p`` [m] moved onto the box, and whether it had to move."""
        lo, hi = self.centre - self.half, self.centre + self.half
        q = np.clip(p, lo, hi)
        return q, bool(np.any(q != p))

    def describe(self) -> dict[str, Any]:
        """The box for the result JSON (min and max corners) [m]."""
        return {"min_m": (self.centre - self.half).tolist(), "max_m": (self.centre + self.half).tolist()}


@dataclass
class TargetCounts:
    """What a live source received: accepted targets, dropped messages (and why, by reason),
    targets clamped onto the workspace, holds (the stream silent for longer than the timeout)."""

    received: int = 0
    dropped: int = 0
    clamped: int = 0
    holds: int = 0
    reasons: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class Target:
    """An accepted target: position [m] in {w} (clamped), rotation (3x3, tip frame -> {w}) or
    None, the sender's time [s] (NaN: none given) and its arrival on the host's monotonic clock [s]."""

    p: Array
    R: Array | None
    t: float
    arrival: float


def _finite_numbers(value: object, n: int) -> list[float] | None:
    if not isinstance(value, list | tuple) or len(value) != n:
        return None
    if not all(isinstance(x, int | float) and not isinstance(x, bool) for x in value):
        return None
    out = [float(x) for x in value]
    return out if all(math.isfinite(x) for x in out) else None


def parse_target(line: str | bytes) -> tuple[float, Array, Array | None]:
    """A JSON line ``{"t": s, "p": [x, y, z], "q": [qx, qy, qz, qw]}`` as (t [s] or NaN, p [m],
    R 3x3 or None); ValueError with a short reason when it is malformed."""
    if len(line) > MAX_LINE:
        raise ValueError(f"line longer than {MAX_LINE} bytes")
    try:
        msg = json.loads(line)
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise ValueError("not JSON") from None
    if not isinstance(msg, dict):
        raise ValueError("not a JSON object")
    p = _finite_numbers(msg.get("p"), 3)
    if p is None:
        raise ValueError('"p" must be 3 finite numbers [m]')
    t = float("nan")
    if "t" in msg:
        tt = msg["t"]
        if not isinstance(tt, int | float) or isinstance(tt, bool) or not math.isfinite(tt):
            raise ValueError('"t" must be a finite number [s]')
        t = float(tt)
    R = None
    if msg.get("q") is not None:
        q = _finite_numbers(msg["q"], 4)
        if q is None:
            raise ValueError('"q" must be 4 finite numbers (x, y, z, w)')
        R = rotation_of_quaternion(np.asarray(q, float))
    return t, np.asarray(p, float), R


def rotation_of_quaternion(q: Array) -> Array:
    """The rotation matrix of the quaternion (x, y, z, w), normalised; ValueError for a zero norm
    (or a norm far from 1: below 0.5 or above 2, a sender's bug rather than rounding)."""
    n = float(np.linalg.norm(q))
    if not (math.isfinite(n) and 0.5 <= n <= 2.0):
        raise ValueError(f"quaternion norm {n:.3g} (need a unit quaternion x, y, z, w)")
    return np.asarray(Rotation.from_quat(q / n).as_matrix(), float)


class LiveTargets:
    """The newest target of a live stream, thread-safe: sources call :meth:`offer_line` or
    :meth:`offer`, the loop reads :meth:`newest`. Positions in {w} [m]; ``timeout`` [s] on
    ``clock`` (the host's monotonic clock)."""

    def __init__(self, workspace: Workspace, timeout: float = TARGET_TIMEOUT_S,
                 clock: Callable[[], float] = time.monotonic, warn: IO[str] | None = None,
                 name: str = "targets") -> None:
        self.workspace = workspace
        self.timeout = float(timeout)
        self.clock = clock
        self.counts = TargetCounts()
        self.name = name
        self._warn = warn
        self._lock = threading.Lock()
        self._newest: Target | None = None

    def offer_line(self, line: str | bytes) -> bool:
        """Parse one JSON line and offer it; a malformed one is dropped (counted, warned)."""
        if isinstance(line, bytes | str) and not line.strip():
            return False  # blank lines (keep-alives) are neither targets nor errors
        try:
            t, p, R = parse_target(line)
        except ValueError as e:
            self.drop(str(e))
            return False
        return self.offer(p, R, t)

    def offer(self, p: Array, R: Array | None = None, t: float = float("nan")) -> bool:
        """Accept the target ``p`` [m] (``R``: tip frame -> {w}, or None) sent at ``t`` [s];
        clamped onto the workspace; dropped when older than the newest accepted."""
        p = np.asarray(p, float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            self.drop("p must be 3 finite numbers [m]")
            return False
        with self._lock:
            last = self._newest
            if last is not None and math.isfinite(t) and math.isfinite(last.t) and t < last.t:
                stale = True
            else:
                stale = False
                q, clamped = self.workspace.clamp(p)
                self.counts.clamped += int(clamped)
                self.counts.received += 1
                self._newest = Target(q, None if R is None else np.asarray(R, float), t, self.clock())
        if stale:
            self.drop("older than the newest target")
            return False
        return True

    def drop(self, reason: str) -> None:
        """Count a dropped message and warn (one line; only the first MAX_WARNINGS)."""
        with self._lock:
            self.counts.dropped += 1
            self.counts.reasons[reason] = self.counts.reasons.get(reason, 0) + 1
            n = self.counts.dropped
        out = self._warn if self._warn is not None else sys.stderr
        if n <= MAX_WARNINGS:
            more = "; further drops are only counted" if n == MAX_WARNINGS else ""
            print(f"wristmark servo: warning: {self.name}: message dropped ({reason}){more}", file=out, flush=True)

    def newest(self) -> tuple[Target | None, bool]:
        """The newest target (None: none yet) and whether it is fresh (within the timeout)."""
        with self._lock:
            target = self._newest
        return target, target is not None and self.clock() - target.arrival <= self.timeout

    def report(self) -> dict[str, Any]:
        """The counts for the result JSON."""
        with self._lock:
            return {**dataclasses.asdict(self.counts), "timeout_s": self.timeout,
                    "workspace": self.workspace.describe()}


class TargetFollower:
    """Where the tip is asked to be on the loop's clock: the newest fresh target, approached at
    most ``max_speed`` [m/s] and ``max_angular_speed`` [rad/s]; held while the stream is silent."""

    def __init__(self, targets: LiveTargets, start: Array, R_start: Array | None,
                 max_speed: float = MAX_SPEED, max_angular_speed: float = MAX_ANGULAR_SPEED) -> None:
        self.targets = targets
        self.p = np.asarray(start, float).copy()
        self.R = None if R_start is None else np.asarray(R_start, float).copy()
        self.max_speed = float(max_speed)
        self.max_angular_speed = float(max_angular_speed)
        self.t: float | None = None
        self.holding = False
        self._lock = threading.Lock()

    def advance(self, t: float) -> None:
        """Move the asked pose on to the loop's time ``t`` [s] (earlier times change nothing)."""
        with self._lock:
            if self.t is None:
                self.t = t
            if t <= self.t:
                return
            dt, self.t = t - self.t, t
            target, fresh = self.targets.newest()
            if target is None:
                return  # nothing received yet: the start is held (not a hold of the stream)
            if not fresh:
                if not self.holding:
                    self.holding = True
                    self.targets.counts.holds += 1
                return
            self.holding = False
            d = target.p - self.p
            dist = float(np.linalg.norm(d))
            step = self.max_speed * dt
            self.p = target.p.copy() if dist <= step else self.p + d * (step / dist)
            if self.R is not None and target.R is not None:
                rv = Rotation.from_matrix(target.R @ self.R.T).as_rotvec()
                ang = float(np.linalg.norm(rv))
                turn = self.max_angular_speed * dt
                if ang > turn:
                    rv = rv * (turn / ang)
                self.R = np.asarray(Rotation.from_rotvec(rv).as_matrix() @ self.R, float)

    def pose(self) -> tuple[Array, Array | None]:
        """The asked position [m] and rotation (None: position only)."""
        with self._lock:
            return self.p.copy(), None if self.R is None else self.R.copy()


@dataclass(frozen=True)
class LiveTrajectory(Trajectory):
    """A :class:`Trajectory` for the servo loop whose samples are the live follower's pose
    (velocity zero: no feed-forward), run for ``hold`` [s]. ``waypoints[0]``: the start [m]."""

    hold: float = 60.0
    follower: TargetFollower | None = None
    kind: str = "stdin"

    @property
    def times(self) -> Array:
        """Start and end [s]."""
        return np.array([0.0, self.hold])

    @property
    def duration(self) -> float:
        """Run time [s]."""
        return float(self.hold)

    def sample(self, t: float) -> tuple[Array, Array]:
        """The asked position [m] at loop time ``t`` [s], at rest (no feed-forward)."""
        if self.follower is None or t <= 0.0:
            return np.asarray(self.waypoints[0], float).copy(), np.zeros(3)
        self.follower.advance(t)
        return self.follower.pose()[0], np.zeros(3)

    def sample_orientation(self, t: float) -> tuple[Array, Array] | None:
        """The asked tip rotation in {w} (None: position only), at rest."""
        if self.orientation is None or self.follower is None:
            return None
        self.follower.advance(max(t, 0.0))
        R = self.follower.pose()[1]
        return (self.orientation.rotations[0].copy() if R is None else R), np.zeros(3)

    def truncated(self, duration: float) -> LiveTrajectory:
        """Run for ``duration`` [s] instead."""
        return dataclasses.replace(self, hold=float(duration))

    def with_follower(self, targets: LiveTargets, max_speed: float = MAX_SPEED,
                      max_angular_speed: float = MAX_ANGULAR_SPEED) -> LiveTrajectory:
        """The same run following ``targets`` from its start (and its orientation, if any)."""
        R0 = None if self.orientation is None else self.orientation.rotations[0]
        return dataclasses.replace(self, follower=TargetFollower(targets, self.waypoints[0], R0, max_speed,
                                                                 max_angular_speed))


def live_trajectory(start: Array, duration: float, kind: str, orientation: OrientationPath | None = None
                    ) -> LiveTrajectory:
    """A live run of ``duration`` [s] starting (and waiting) at ``start`` [m] in {w}."""
    return LiveTrajectory(np.asarray([start], float), 1.0, orientation, hold=float(duration), kind=kind)


# -- the line sources ------------------------------------------------------------------------------
def parse_target_spec(spec: str) -> tuple[str, str | None, int | None]:
    """``--target SPEC``: (kind, host, port); kinds cube | point (built-in) | stdin | tcp | ros2.
    ``tcp:127.0.0.1:PORT`` / ``tcp:PORT`` listen on loopback only (PORT 0: any free port)."""
    if spec in ("cube", "point", "stdin", "ros2"):
        return spec, None, None
    if spec.startswith("tcp:"):
        rest = spec[4:]
        host, _, port_s = rest.rpartition(":")
        host = host or "127.0.0.1"
        if host not in LOOPBACK_HOSTS:
            raise InputError(f"--target {spec}: targets are taken on loopback only (tcp:127.0.0.1:PORT), "
                             f"not {host!r}")
        try:
            port = int(port_s)
        except ValueError:
            port = -1
        if not 0 <= port <= 65535:
            raise InputError(f"--target {spec}: PORT must be an integer 0..65535 (0: any free port)")
        return "tcp", "127.0.0.1", port
    raise InputError(f"--target must be cube, point, stdin, tcp:127.0.0.1:PORT or ros2, got {spec!r}")


class LineSource:
    """Feeds JSON lines from a thread into :class:`LiveTargets` until closed."""

    def __init__(self, targets: LiveTargets) -> None:
        self.targets = targets
        self.describe = ""
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def _spawn(self, fn: Callable[..., None], *args: Any) -> None:
        th = threading.Thread(target=fn, args=args, daemon=True, name=f"wristmark-targets-{len(self._threads)}")
        self._threads.append(th)
        th.start()

    def _read_lines(self, stream: IO[bytes]) -> None:
        """Offer every line of ``stream`` until its end or :meth:`close`."""
        while not self._stop.is_set():
            line = stream.readline(MAX_LINE + 1)
            if not line:
                return
            if len(line) > MAX_LINE:  # the rest of an over-long line is skipped
                while line and not line.endswith(b"\n"):
                    line = stream.readline(MAX_LINE + 1)
                self.targets.drop(f"line longer than {MAX_LINE} bytes")
                continue
            self.targets.offer_line(line)

    def close(self) -> None:
        """Stop reading (threads blocked on a stream end with the process: they are daemons)."""
        self._stop.set()

    def __enter__(self) -> LineSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class StdinTargets(LineSource):
    """JSON lines on standard input (``--target stdin``).

    Standard input is read from its file descriptor with ``select`` and ``os.read``, never
    through ``sys.stdin``: a thread blocked in ``sys.stdin.buffer.readline`` holds the buffer's
    lock, and the interpreter aborts at shutdown ("could not acquire lock for <stdin>") when it
    finalizes ``sys.stdin``. This thread sees :meth:`close` within 0.1 s and ends."""

    def __init__(self, targets: LiveTargets, stream: IO[bytes] | None = None) -> None:
        super().__init__(targets)
        self.describe = "stdin"
        if stream is not None:
            self._spawn(self._read_lines, stream)
        else:
            self._spawn(self._read_fd, 0)  # fd 0 itself: sys.stdin may be replaced (a test harness)

    def _read_fd(self, fd: int) -> None:
        """Offer every line read from file descriptor ``fd`` until its end or :meth:`close`."""
        pending = b""
        skipping = False  # inside an over-long line, until its newline
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([fd], [], [], 0.1)
                if not ready:
                    continue
                chunk = os.read(fd, 65536)
            except (OSError, ValueError):
                return
            if not chunk:
                if pending and not skipping:
                    self.targets.offer_line(pending)
                return
            pending += chunk
            while True:
                end = pending.find(b"\n")
                if end < 0:
                    if len(pending) > MAX_LINE and not skipping:
                        self.targets.drop(f"line longer than {MAX_LINE} bytes")
                        skipping = True
                    if skipping:
                        pending = b""
                    break
                line, pending = pending[: end + 1], pending[end + 1:]
                if skipping:
                    skipping = False
                elif len(line) > MAX_LINE:
                    self.targets.drop(f"line longer than {MAX_LINE} bytes")
                else:
                    self.targets.offer_line(line)


class TcpTargets(LineSource):
    """JSON lines from clients of a TCP server on loopback (``--target tcp:127.0.0.1:PORT``);
    several clients may connect, each line goes to the same store."""

    def __init__(self, targets: LiveTargets, port: int, host: str = "127.0.0.1") -> None:
        super().__init__(targets)
        if host not in LOOPBACK_HOSTS:
            raise InputError(f"targets are taken on loopback only, not {host!r}")
        self._server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._server.bind(("127.0.0.1", port))
        except OSError as e:
            self._server.close()
            raise InputError(f"--target tcp:127.0.0.1:{port}: cannot listen ({e.strerror or e})") from None
        self._server.listen(4)
        self._server.settimeout(0.1)
        self.port = int(self._server.getsockname()[1])
        self.describe = f"tcp:127.0.0.1:{self.port}"
        self._clients: list[socket.socket] = []
        self._spawn(self._accept)

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(None)
            self._clients.append(conn)
            self._spawn(self._serve, conn)

    def _serve(self, conn: socket.socket) -> None:
        with conn, conn.makefile("rb") as stream:
            try:
                self._read_lines(stream)
            except OSError:
                return

    def close(self) -> None:
        """Stop accepting and close every connection."""
        super().close()
        self._threads[0].join(timeout=1.0)  # the accept loop wakes every 0.1 s and sees the stop
        for conn in self._clients:  # wakes a thread blocked reading it
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        for s in (self._server, *self._clients):
            try:
                s.close()
            except OSError:
                pass


def open_live_targets(traj: LiveTrajectory, workspace: Workspace, port: int | None, timeout: float,
                      max_speed: float, name: str, who: str = ""
                      ) -> tuple[LiveTrajectory, LiveTargets, LineSource | None]:
    """``traj`` following a new target store (``workspace``, ``timeout`` [s], ``max_speed`` [m/s];
    ``name`` in its warnings) fed by its stdin or TCP source (ros2: none here, the bridge feeds
    it); a TCP server's address is printed on stderr (``who``: "arm a " with several arms)."""
    targets = LiveTargets(workspace, timeout=timeout, name=name)
    source = open_line_source(traj.kind, targets, port) if traj.kind in ("stdin", "tcp") else None
    if source is not None and traj.kind == "tcp":
        print(f"wristmark servo: {who}taking targets on {source.describe}", file=sys.stderr, flush=True)
    return traj.with_follower(targets, max_speed), targets, source


def open_line_source(kind: str, targets: LiveTargets, port: int | None = None) -> LineSource:
    """The stdin or TCP source feeding ``targets`` (``kind``: stdin | tcp)."""
    if kind == "stdin":
        return StdinTargets(targets)
    if kind == "tcp":
        return TcpTargets(targets, int(port or 0))
    raise InputError(f"no line source {kind!r} (stdin | tcp)")
