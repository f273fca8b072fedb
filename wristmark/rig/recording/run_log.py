"""Per-cycle records of a servo run and the run folder they are written to.

``log.csv`` columns (SI: s, m, rad): t (the loop's clock: simulated time, or the wall clock's
on hardware), t_wall (the cycle's ``time.monotonic()``), phase, p_des_{x,y,z}, p_cmd_{x,y,z}
(model tip at the commanded configuration), p_est_{x,y,z} (vision estimate, empty when none),
p_true_{x,y,z}, p_trk_{x,y,z} (optical tracker), psi_cmd_0..5, psi_true_0..5 (the reference arm;
any other arm (a format-2 robot file): psi_cmd_<name>, psi_true_<name> per entry of its psi, e.g.
psi_cmd_d, psi_cmd_theta1, psi_cmd_delta1, ...; the truth columns are empty without a
ground-truth observer: on hardware), meas_ok, rejected, vision_ms, ctrl_us,
t_capture (the measured frame's capture time on the frames' clock [s], empty without a frame),
latency_ms (capture -> command of the cycle's accepted measurement [ms], empty otherwise),
transport_ms (capture -> the frame available to the loop [ms]: the part of the latency before
the host could act; empty when unknown); then the tip frame's orientations in {w} as rotation
vectors [rad]: rot_des_{x,y,z} (desired; empty when the trajectory asks for none), rot_est_{x,y,z}
(measured by vision; empty when not measured), rot_true_{x,y,z}, rot_trk_{x,y,z} (6-DoF optical
tracker), and orientation_error (angle between the tracker's and the desired orientation [rad];
empty when either is missing); then the actuators as the box saw them: t_act (when the encoders
were read, on the frames' clock, as t_capture [s]), act_cmd_<name> (the target last sent to the
box, after any ``--model`` link) and act_meas_<name> (its encoder readings) per actuator
(models.arm_spec.actuator_names: phi, d, s1a, s1b, s2a, s2b for the reference arm) [rad or m]:
what ``wristmark identify --from-log RUN`` fits; open_on_lost (1: the marker lost, the cycle
walked on open loop); tip_sigma (the measured tip's own standard deviation [m] as the tracker
reported it, cvs.tracking.result.TrackResult.tip_sigma_m; empty without a measurement or an
estimate).
``config.json`` holds every configuration used; ``result.json`` the metrics.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.so3 import angle_between, rotvec

Array = NDArray[np.float64]

_XYZ = ("x", "y", "z")
REFERENCE_ACTUATORS = ("phi", "d", "s1a", "s1b", "s2a", "s2b")


def log_columns(psi_names: tuple[str, ...] | None = None,
                act_names: tuple[str, ...] = REFERENCE_ACTUATORS) -> tuple[str, ...]:
    """log.csv's columns; ``psi_names``: the arm's names of psi's entries (None: the reference
    arm's columns psi_cmd_0..5, psi_true_0..5); ``act_names``: its actuators' names."""
    tags = tuple(str(i) for i in range(6)) if psi_names is None else psi_names
    return (
        ("t", "t_wall", "phase")
        + tuple(f"p_{k}_{a}" for k in ("des", "cmd", "est", "true", "trk") for a in _XYZ)
        + tuple(f"psi_cmd_{i}" for i in tags)
        + tuple(f"psi_true_{i}" for i in tags)
        + ("meas_ok", "rejected", "vision_ms", "ctrl_us", "t_capture", "latency_ms",
           "transport_ms")
        + tuple(f"rot_{k}_{a}" for k in ("des", "est", "true", "trk") for a in _XYZ)
        + ("orientation_error", "t_act")
        + tuple(f"act_{k}_{a}" for k in ("cmd", "meas") for a in act_names)
        + ("open_on_lost", "tip_sigma")
    )


COLUMNS: tuple[str, ...] = log_columns()


@dataclass
class CycleRecord:
    """One servo cycle; positions in {w} [m], configurations [rad, m]; times [s] (see the
    module docstring); NaN where unknown."""

    t: float
    phase: str
    p_des: Array
    p_cmd: Array
    p_est: Array | None
    p_true: Array
    p_trk: Array
    psi_cmd: Array
    psi_true: Array
    meas_ok: bool
    rejected: bool
    vision_ms: float
    ctrl_us: float
    t_wall: float = math.nan
    t_capture: float = math.nan
    latency_ms: float = math.nan
    transport_ms: float = math.nan
    R_des: Array | None = None
    R_est: Array | None = None
    R_true: Array | None = None
    R_trk: Array | None = None
    T_marker_est: Array | None = None  # the measured marker pose {wm} in {w} (4x4), when p_est is; not in log.csv
    t_act: float = math.nan
    act_cmd: Array | None = None  # the box's last target [rad or m each] (None: unknown)
    act_meas: Array | None = None  # its encoder readings at t_act
    open_on_lost: bool = False  # the marker lost, the loop walked on along the target open loop (rig open_loop_on_lost)
    tip_sigma: float = math.nan  # [m] the measured tip's own standard deviation (TrackResult.tip_sigma_m)

    def orientation_error(self, which: str = "R_trk") -> float:
        """Angle [rad] between the orientation ``which`` (R_trk, R_true or R_est) and the
        desired one; NaN when either is unknown."""
        R = getattr(self, which)
        if self.R_des is None or R is None or not np.all(np.isfinite(R)):
            return math.nan
        return angle_between(self.R_des, R)

    def row(self, actuators: int = 6) -> list[Any]:
        """CSV row in COLUMNS order (``actuators``: the arm's count, for the act_ columns)."""
        est = self.p_est if self.p_est is not None else [math.nan] * 3
        vals: list[Any] = [f"{self.t:.6f}", _num(self.t_wall, "{:.6f}"), self.phase]
        for v in (self.p_des, self.p_cmd, est, self.p_true, self.p_trk, self.psi_cmd, self.psi_true):
            vals += ["" if not math.isfinite(x) else f"{x:.9g}" for x in np.asarray(v, float)]
        vals += [int(self.meas_ok), int(self.rejected), f"{self.vision_ms:.3f}", f"{self.ctrl_us:.1f}",
                 _num(self.t_capture, "{:.6f}"), _num(self.latency_ms, "{:.3f}"), _num(self.transport_ms, "{:.3f}")]
        for R in (self.R_des, self.R_est, self.R_true, self.R_trk):
            ok = R is not None and bool(np.all(np.isfinite(R)))
            vals += [f"{x:.9g}" for x in rotvec(R)] if ok and R is not None else ["", "", ""]
        vals.append(_num(self.orientation_error(), "{:.9g}"))
        vals.append(_num(self.t_act, "{:.6f}"))
        for a in (self.act_cmd, self.act_meas):
            vals += [_num(float(x), "{:.9g}") for x in np.asarray(a, float)] if a is not None else [""] * actuators
        vals.append(int(self.open_on_lost))
        vals.append(_num(self.tip_sigma, "{:.6g}"))
        return vals


def _num(x: float, fmt: str) -> str:
    """A CSV cell: formatted, or empty when not finite."""
    return fmt.format(x) if math.isfinite(x) else ""


@dataclass
class RunLog:
    """All cycles of one or more phases of a run (:class:`CycleRecord`: {w} [m], [s])."""

    records: list[CycleRecord] = field(default_factory=list)
    psi_names: tuple[str, ...] | None = None  # the arm's psi names (None: the reference arm, psi_cmd_0..5)
    act_names: tuple[str, ...] = REFERENCE_ACTUATORS  # the arm's actuator names (act_cmd_<name>, act_meas_<name>)

    @classmethod
    def for_arm(cls, arm: Any) -> RunLog:
        """An empty log named for ``arm`` (models.arm_spec.Arm): its psi and actuator names."""
        from wristmark.models.arm_spec import actuator_names, log_psi_names

        return cls(psi_names=log_psi_names(arm), act_names=actuator_names(arm))

    def add(self, rec: CycleRecord) -> None:
        """Append a cycle."""
        self.records.append(rec)

    def phase(self, name: str) -> list[CycleRecord]:
        """The records of one phase."""
        return [r for r in self.records if r.phase == name]

    def write_csv(self, path: str | Path) -> None:
        """Write log.csv."""
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(log_columns(self.psi_names, self.act_names))
            for r in self.records:
                w.writerow(r.row(len(self.act_names)))


def read_log_csv(path: str | Path) -> dict[str, Array | list[str]]:
    """Read a log.csv into columns (floats; 'phase' as strings; empty cells as NaN)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    out: dict[str, Array | list[str]] = {}
    if not rows:
        return out
    for k in rows[0]:
        if k == "phase":
            out[k] = [r[k] for r in rows]
        else:
            out[k] = np.array([float(r[k]) if r[k] != "" else math.nan for r in rows])
    return out


def write_json(path: str | Path, data: dict[str, Any]) -> None:
    """Write JSON with a trailing newline (NaN written as null)."""

    def clean(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [clean(x) for x in v]
        if isinstance(v, np.ndarray):
            return clean(v.tolist())
        if isinstance(v, float | np.floating):
            return float(v) if math.isfinite(v) else None
        if isinstance(v, np.integer):
            return int(v)
        return v

    Path(path).write_text(json.dumps(clean(data), indent=2) + "\n")
