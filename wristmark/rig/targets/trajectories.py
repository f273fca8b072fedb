"""Desired tip paths: the paper's cube (IV.C) and the incremental accuracy targets (IV.B); a path
may carry an orientation for the tip frame (rig/targets/orientation_path.py: none | hold | follow)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from wristmark.models.arm_spec import Arm, home_psi
from wristmark.models.errors import InputError
from wristmark.models.kinematics import tip_position
from wristmark.rig.targets.orientation_path import OrientationPath, orientation_path

Array = NDArray[np.float64]
CUBE_SIZE = (0.040, 0.020, 0.040)  # [m] edges along x_w, y_w (depth from the camera), z_w (paper: 40 x 20 x 40 mm)
CUBE_SPEED = 0.010  # [m/s] (paper: 10 mm/s)
MIN_SEGMENT = 1e-6  # [m] consecutive waypoints closer than this are a mistake (a zero-length segment)

# Corner order of a walk that covers all 12 edges of a box (4 edges twice): bottom square,
# up, top square, the remaining verticals and back to the start (a closed walk).
# Signs of (x, y, z) relative to the centre.
_CUBE_WALK = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, -1), (-1, -1, 1),
              (1, -1, 1), (1, 1, 1), (-1, 1, 1), (-1, -1, 1), (1, -1, 1), (1, -1, -1),
              (1, 1, -1), (1, 1, 1), (-1, 1, 1), (-1, 1, -1), (-1, -1, -1)]


@dataclass(frozen=True)
class Trajectory:
    """Piecewise-linear path through ``waypoints`` (N,3) [m] at ``speed`` [m/s]; ``orientation``:
    the tip frame's desired orientation along it (None: position only). From your own points in
    {w}: :meth:`from_waypoints` (validated)."""

    waypoints: Array
    speed: float
    orientation: OrientationPath | None = None

    @classmethod
    def from_waypoints(cls, points_world: ArrayLike, speed: float) -> Trajectory:
        """The path through ``points_world`` (N >= 2, 3) in {w} [m], in order, at ``speed`` [m/s]:
        dense samples of a curve (a circle every few degrees) give a smooth path; repeat the first
        point at the end to close it. InputError (one line) for a bad shape, a non-finite value,
        two consecutive points closer than 1 um or a speed that is not > 0."""
        try:
            pts = np.array(points_world, dtype=float)
        except (TypeError, ValueError) as e:
            raise InputError(f"waypoints must be numbers, shape (N, 3) [m]: {e}") from None
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 2:
            raise InputError(f"waypoints must have shape (N, 3) with N >= 2 [m], got {pts.shape}")
        bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
        if bad.size:
            raise InputError(f"waypoint {bad[0]} is not finite: {pts[bad[0]].tolist()}")
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        short = np.flatnonzero(seg < MIN_SEGMENT)
        if short.size:
            raise InputError(f"waypoints {short[0]} and {short[0] + 1} coincide (closer than 1 um): "
                             "drop the repeat")
        if isinstance(speed, bool) or not isinstance(speed, (int, float, np.floating)) or not (
                np.isfinite(speed) and speed > 0):
            raise InputError(f"speed must be a finite number > 0 [m/s], got {speed!r}")
        return cls(pts, float(speed))

    @property
    def orientation_mode(self) -> str:
        """none | hold | follow."""
        return "none" if self.orientation is None else self.orientation.mode

    def with_orientation(self, mode: str, params: Arm) -> Self:
        """The same path asking for the orientation ``mode`` (none | hold | follow) of the tip frame."""
        return dataclasses.replace(self, orientation=orientation_path(mode, params, lambda t: self.sample(t)[0],
                                                                      self.duration))

    def sample_orientation(self, t: float) -> tuple[Array, Array] | None:
        """Desired tip-frame rotation (3x3) in {w} and angular velocity [rad/s] in {w} at time t
        (None: the path asks for none)."""
        return None if self.orientation is None else self.orientation.sample(t)

    @property
    def times(self) -> Array:
        """Arrival time at each waypoint [s]."""
        seg = np.linalg.norm(np.diff(self.waypoints, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(seg) / self.speed])

    @property
    def duration(self) -> float:
        """Total time [s]."""
        return float(self.times[-1])

    def sample(self, t: float) -> tuple[Array, Array]:
        """Desired position [m] and velocity [m/s] at time t (held at the ends)."""
        ts = self.times
        if t <= 0.0:
            return self.waypoints[0].copy(), np.zeros(3)
        if t >= ts[-1]:
            return self.waypoints[-1].copy(), np.zeros(3)
        i = int(np.searchsorted(ts, t, side="right")) - 1
        a, b = self.waypoints[i], self.waypoints[i + 1]
        d = b - a
        L = float(np.linalg.norm(d))
        u = d / L
        return a + u * self.speed * (t - ts[i]), u * self.speed

    def truncated(self, duration: float) -> Trajectory:
        """The first ``duration`` seconds of the path (the whole path if it is shorter)."""
        if not duration > 0:
            raise ValueError(f"duration must be > 0 s, got {duration}")
        ts = self.times
        if duration >= ts[-1]:
            return self
        k = int(np.searchsorted(ts, duration, side="right"))
        end = self.sample(duration)[0]
        pts = np.vstack([self.waypoints[:k], end]) if not np.isclose(ts[k - 1], duration) else self.waypoints[:k]
        orient = None if self.orientation is None else self.orientation.shifted(duration)
        return Trajectory(pts, self.speed, orient)


def feedforward_velocity(traj: Trajectory, t: float, dt: float, preview: float, lead: float) -> Array:
    """Tip velocity [m/s] that moves a command from p_ff(t) to p_ff(t + dt) over one cycle of
    ``dt`` [s], where p_ff(s) = p_des(s + preview) + lead * v_des(s + preview): the desired path
    ``preview`` [s] ahead (the loop's delay) plus a first-order lead of ``lead`` [s] (the
    actuators' lag; at a corner the lead turns the change of velocity into a short burst)."""
    p0, v0 = traj.sample(t + preview)
    p1, v1 = traj.sample(t + dt + preview)
    return (p1 + lead * v1 - p0 - lead * v0) / dt


REACH_MARGIN = 0.005  # [m] a cube moved into the arm's reach goes this much further in (workspace_centre)


def workspace_centre(params: Arm, size: tuple[float, float, float] = CUBE_SIZE,
                     margin: float = REACH_MARGIN) -> Array:
    """The cube's centre in {w} [m]: the tip at the home configuration; when a corner of the cube
    of edges ``size`` [m] around it lies beyond the arm's nominal reach (the tip IK from home
    falls short), moved until every corner is reached, then ``margin`` [m] further the same way
    (room for the closed loop to drive the true arm, whose errors ask for more, to the corner).
    An arm that reaches the cube around its home tip (the reference arm) keeps the home tip."""
    from wristmark.models.ik import solve_tip_ik

    q0 = home_psi(params)
    home = tip_position(params, q0)
    centre = home.copy()
    corners = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    corners *= 0.5 * np.asarray(size, float)
    for _ in range(40):
        short = np.array([tip_position(params, solve_tip_ik(params, centre + c, q0).psi) - (centre + c)
                          for c in corners])  # reached - asked, per corner [m]
        if np.max(np.linalg.norm(short, axis=1)) <= 1e-6:
            break
        centre = centre + short.mean(0) + short[np.argmax(np.linalg.norm(short, axis=1))] / len(corners)
    moved = centre - home
    if np.linalg.norm(moved) > 1e-6:
        centre = centre + margin * moved / np.linalg.norm(moved)
    return centre


def cube_trajectory(centre_world: Array, size: tuple[float, float, float] = CUBE_SIZE,
                    speed: float = CUBE_SPEED) -> Trajectory:
    """All 12 edges of a box of edge lengths ``size`` (x_w, y_w, z_w) [m] around the centre."""
    c = np.asarray(centre_world, float)
    half = 0.5 * np.asarray(size, float)
    pts = np.array([c + half * np.array(s) for s in _CUBE_WALK])
    return Trajectory(pts, speed)


def accuracy_targets(centre_world: Array, n: int = 40, seed: int = 0, box: float = 0.030,
                     step: tuple[float, float] = (0.002, 0.006)) -> Array:
    """``n`` positions (n,3) [m] reached by incremental moves of ``step`` length inside a cube of
    edge ``box`` around the centre (paper IV.B)."""
    rng = np.random.default_rng(seed)
    c = np.asarray(centre_world, float)
    p = c.copy()
    out: list[Array] = []
    while len(out) < n:
        d = rng.normal(size=3)
        q = p + d / np.linalg.norm(d) * rng.uniform(*step)
        if np.all(np.abs(q - c) <= box / 2):
            p = q
            out.append(p.copy())
    return np.asarray(out)
