"""Regenerates the measured tables of docs/results.md and the README's results table.

Runs the canonical command of each result (below: ``--list`` prints them), each in a fresh
process with a bounded run time, keeps its JSON output and a note of when, where and how long it
ran under runs/results/, and rewrites

- in docs/results.md every block between ``<!-- generated:NAME:start -->`` and
  ``<!-- generated:NAME:end -->`` whose result is at hand (the prose outside the blocks is
  hand-written and left alone; a block starts with the command that produces it);
- in README.md the block between ``<!-- results-table:start -->`` and
  ``<!-- results-table:end -->``: at most 6 rows beside the paper's numbers, each value written
  exactly as in docs/results.md (tests/project/test_results_doc.py checks it).

    .venv/bin/python bench/results.py                 # every result, one after the other
    .venv/bin/python bench/results.py --only cube --only tracking
    .venv/bin/python bench/results.py --list          # names, commands and time limits
    .venv/bin/python bench/results.py --collect-only  # rewrite the docs from runs/results/ alone

A command that fails or runs out of time leaves its block as it was (and says so on stderr).
With ``--only`` only those results' blocks and README rows are rewritten: the others keep their
text even where an older result is kept under runs/results/.
Timings are medians of the machine's run; on a shared machine compare the ratios a bench prints
against its own same-run baseline, not the absolute times.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime as dt
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS_MD = ROOT / "docs" / "results.md"
README = ROOT / "README.md"
OUT = Path("runs/results")  # relative to ROOT, as the commands are written
README_START, README_END = "<!-- results-table:start -->", "<!-- results-table:end -->"

# The paper's numbers (Sec. IV): cube, Fig. 8; accuracy, IV.B; image processing time, IV.A.
PAPER = {"open_mean": 3.25, "open_max": 8.40, "closed_mean": 0.82, "closed_max": 2.59, "ratio_pct": 25.2,
         "accuracy_mean": 0.67, "accuracy_max": 1.21, "processing_ms": 45, "cycle_ms": 60}

Render = Callable[[dict[str, Any]], list[str]]


@dataclasses.dataclass(frozen=True)
class Entry:
    """One canonical command. ``argv`` is written as a user types it from the repository root
    (``wristmark ...`` or ``.venv/bin/python bench/...``); its JSON is its stdout unless
    ``json_file`` names the file it writes (or a folder's results.csv, read by ``load``)."""

    name: str
    title: str
    argv: tuple[str, ...]
    timeout_s: float
    render: Render
    json_file: str | None = None
    load: Callable[[Path], dict[str, Any]] | None = None
    clean: str | None = None  # an output folder under runs/results/ emptied before the run

    @property
    def command(self) -> str:
        return shlex.join(self.argv)


def _f(x: Any, nd: int = 2) -> str:
    """A number as the docs print it ("-" for a missing one)."""
    if x is None or (isinstance(x, float) and x != x):
        return "-"
    return f"{float(x):.{nd}f}"


def _mm(d: dict[str, Any], nd: int = 3) -> str:
    return f"{_f(d.get('mean_mm'), nd)} / {_f(d.get('max_mm'), nd)}"


# ----------------------------------------------------------------------------- renderers


def cube_rows(r: dict[str, Any]) -> dict[str, str]:
    """The cube's numbers as written in both documents (README rows reuse these strings)."""
    o, c = r["open_loop"], r["closed_loop"]
    return {"open": f"{_f(o['mean_mm'], 2)} / {_f(o['max_mm'], 2)}", "closed": _mm(c),
            "ratio": f"{100 * r['ratio']:.1f} %"}


def render_cube(r: dict[str, Any]) -> list[str]:
    o, c = r["open_loop"], r["closed_loop"]
    v = c.get("vision_vs_true") or {}
    m = c.get("measurements") or {}
    s = cube_rows(r)
    lines = [
        f"Controller `{r.get('controller')}`, {1000 * r.get('control_dt_s', 0):.0f} ms cycle, sensor "
        f"{r.get('sensor')}, orientation {r.get('orientation')}; errors are the simulated optical "
        "tracker's tip against the desired tip.",
        "",
        "| | open loop mean / max [mm] | closed loop mean / max [mm] | closed / open | "
        "corner overshoot max / mean [mm] | vision vs true tip mean / max [mm] | measurements accepted |",
        "|---|---|---|---|---|---|---|",
        f"| paper (Fig. 8) | {PAPER['open_mean']:.2f} / {PAPER['open_max']:.2f} | "
        f"{PAPER['closed_mean']:.2f} / {PAPER['closed_max']:.2f} | {PAPER['ratio_pct']:.1f} % | - | - | - |",
        f"| wristmark | {s['open']} | {s['closed']} | {s['ratio']} | "
        f"{_f(c['corner_overshoot_mm']['max'])} / {_f(c['corner_overshoot_mm']['mean'])} | "
        f"{_mm(v)} | {m.get('accepted', '-')} of {c.get('cycles', '-')} |",
    ]
    nf = c.get("noise_free") or {}
    extra = [f"noise-free closed loop {_mm(nf)} mm"]
    if c.get("orientation_mean_deg") is not None:
        extra.append(f"closed-loop orientation {_f(c['orientation_mean_deg'])} / {_f(c.get('orientation_max_deg'))} deg"
                     f" (open loop {_f(o.get('orientation_mean_deg'))} / {_f(o.get('orientation_max_deg'))} deg)")
    if c.get("vision_ms_median"):
        extra.append(f"tracking in the loop {_f(c['vision_ms_median'], 1)} ms per stereo pair (median)")
    probe = c.get("play_probe")
    if isinstance(probe, str):
        extra.append(probe)
    elif isinstance(probe, list) and probe:
        taus = [1000 * f["motor_tau"] for f in probe if f.get("motor_tau") == f.get("motor_tau") and f.get("motor_tau")]
        lag = f", motor lags {min(taus):.1f}-{max(taus):.1f} ms" if taus else ""
        extra.append(f"play probe before the walk: {sum(bool(f.get('ok')) for f in probe)} of {len(probe)} fits "
                     f"accepted{lag} (the fits in result.json)")
    if c.get("stopped"):
        extra.append(f"**stopped: {c['stopped']}**")
    return [*lines, "", "; ".join(extra) + "."]


def render_accuracy(r: dict[str, Any]) -> list[str]:
    t = r.get("vs_noise_free_truth") or {}
    return [
        "| | positions tracked | stereo vs optical tracker mean / max [mm] | stereo vs true tip mean / max [mm] |",
        "|---|---|---|---|",
        f"| paper (IV.B) | 40 | {PAPER['accuracy_mean']:.2f} / {PAPER['accuracy_max']:.2f} | - |",
        f"| wristmark | {r['tracked']} of {r['positions']} | {_mm(r)} | {_mm(t)} |",
    ]


def render_tracking(r: dict[str, Any]) -> list[str]:
    t = r.get("targets", {})
    lines = [
        f"{r['pairs']} rendered 1080p stereo pairs (default render noise); per pair, cold = whole frame, "
        "ROI = the same pair again in ROI tracking; times are medians of this run.",
        "",
        "| | corner RMS [px] | tip error mean / max [mm] | success | cold [ms/pair] | ROI [ms/pair] |",
        "|---|---|---|---|---|---|",
        f"| target | <= {_f(t.get('corner_rms_px'))} | mean <= {_f(t.get('tip_error_mean_mm'), 1)} | | "
        f"<= {_f(t.get('time_ms_cold'), 0)} | <= {_f(t.get('time_ms_roi'), 0)} |",
    ]
    names = {"paper": "paper's detector (ours)", "saddle": "saddle fallback (ours)", "auto": "auto (ours)"}
    for k, o in r.get("ours", {}).items():
        lines.append(f"| {names.get(k, k)} | {_f(o.get('corner_rms_px'), 3)} | {_f(o.get('tip_error_mean_mm'), 3)} / "
                     f"{_f(o.get('tip_error_max_mm'), 3)} | {100 * o.get('success_rate', 0):.0f} % | "
                     f"{_f(o.get('time_ms_cold_median'), 1)} | {_f(o.get('time_ms_roi_median'), 1)} |")
    g = r.get("baseline_gftt_oracle_same_solve")
    if g:
        lines.append(f"| baseline: goodFeaturesToTrack + cornerSubPix, same solve | {_f(g.get('corner_rms_px'), 3)} | "
                     f"{_f(g.get('tip_error_mean_mm'), 3)} / {_f(g.get('tip_error_max_mm'), 3)} | "
                     f"{100 * g.get('success_rate', 0):.0f} % | {_f(g.get('time_ms_median'), 1)} | - |")
    p = r.get("baseline_pnp_sqpnp_left_only")
    if p:
        lines.append(f"| baseline: left-camera solvePnP (SQPNP) | - | {_f(p.get('tip_error_mean_mm'), 2)} / "
                     f"{_f(p.get('tip_error_max_mm'), 2)} | {100 * p.get('success_rate', 0):.0f} % | "
                     f"{_f(p.get('time_ms_median'), 1)} | - |")
    d = r.get("detector_only_paper")
    notes = []
    if d:
        notes.append(f"the paper's detector alone: {_f(d.get('time_ms_per_image_cold_median'), 1)} ms per image whole "
                     f"frame, {_f(d.get('time_ms_per_image_roi_median'), 2)} ms in its ROI; corner RMS "
                     f"{_f(d.get('corner_rms_px'), 3)} px with the default refinement against "
                     f"{_f(d.get('corner_rms_px_eq10_quadric'), 3)} px from the paper's eq. 10 quadric alone")
    cs = r.get("coded_sleeve")
    if cs:
        c = cs.get("coded", {})
        notes.append(f"coded sleeve at the same poses: success {100 * c.get('success_rate', 0):.0f} %, roll known "
                     f"{100 * c.get('roll_known_rate', 0):.0f} %, roll error "
                     f"{_f(c.get('roll_error_deg', {}).get('mean'), 3)} / "
                     f"{_f(c.get('roll_error_deg', {}).get('max'), 3)} deg, code reading "
                     f"{_f(c.get('code_ms_median'), 2)} ms per pair")
    ours = r.get("ours", {}).get("paper")
    if ours:
        notes.append(f"the paper's image processing took about {PAPER['processing_ms']} ms per stereo pair "
                     f"(C++, a laptop i7); its control cycle was {PAPER['cycle_ms']} ms")
    return [*lines, "", *(f"- {n}." for n in notes)]


def render_kinematics(r: dict[str, Any]) -> list[str]:
    c = r["closed_form"]
    lines = [
        f"Median over {r['repeats']} repeats of the mean time per call over {r['calls']} random configurations "
        "[us]; the controller uses the closed form.",
        "",
        "| | FK [us] | tip Jacobian [us] | FK + Jacobian [us] |",
        "|---|---|---|---|",
        f"| closed form (the controller's path) | {_f(c['fk_us'], 1)} | {_f(c['jacobian_us'], 1)} | "
        f"{_f(c['fk_plus_jacobian_us'], 1)} |",
    ]
    for n, p in r.get("pinocchio", {}).items():
        lines.append(f"| Pinocchio, N = {n} links per segment | {_f(p['fk_us'], 1)} | {_f(p['jacobian_us'], 1)} | "
                     f"{_f(p['fk_plus_jacobian_us'], 1)} |")
    return [*lines, "", f"Aim for the controller's path: {_f(r.get('aim_us'), 0)} us "
            f"({'met' if r.get('controller_path_under_aim') else 'not met'})."]


def render_controllers(r: dict[str, Any]) -> list[str]:
    return [
        "| | step [us, median] | steps to 10 um (a 3.7 mm step) |",
        "|---|---|---|",
        f"| `paper` (eq. 17-21) | {_f(r['paper_step_us_median'], 1)} | {r['paper_steps_to_10um']} |",
        f"| `qp` | {_f(r['qp_step_us_median'], 1)} | {r['qp_steps_to_10um']} |",
        "",
        f"qp / paper step time in the same run: {_f(r['qp_over_paper_step_ratio'])}; the raw box QP alone: daqp "
        f"{_f(r['qp_raw_solve_us_median_daqp'], 1)} us, qpOASES "
        f"{_f(r['qp_raw_solve_us_median_qpoases'], 1)} us (median).",
    ]


def render_backlash(r: dict[str, Any]) -> list[str]:
    rows: dict[float, dict[bool, dict[str, Any]]] = {}
    for row in r["rows"]:
        rows.setdefault(row["factor"], {})[row["compensation"]] = row
    lines = [
        f"Sensor {r['sensor']}, seeds {r['seeds']}, configs/plant_unseen.yaml's play x factor; the shipped "
        "controller file with its dead-band inversion off and on; closed loop mean / max and corner overshoot "
        "max [mm] (median over the seeds).",
        "",
        "| play factor | inversion off | inversion on |",
        "|---|---|---|",
    ]
    for f in sorted(rows):
        cells = []
        for comp in (False, True):
            x = rows[f].get(comp)
            cells.append("-" if x is None else f"{_f(x['mean_mm'])} / {_f(x['max_mm'])}, "
                         f"{_f(x.get('corner_overshoot_max_mm'))}")
        lines.append(f"| {f:g} | {cells[0]} | {cells[1]} |")
    below = r.get("factors_below_limit", {})
    lines += ["", "Factors whose max stays at or below " + _f(r.get("limit_mm"), 1) + " mm: "
              + "; ".join(f"{k}: {', '.join(f'{x:g}' for x in v) or 'none'}" for k, v in below.items()) + "."]
    return lines


def render_chessboard(r: dict[str, Any]) -> list[str]:
    lines = [
        f"{r['pairs']} real stereo pairs of OpenCV's sample set ({r['pattern'][0]}x{r['pattern'][1]} inner corners).",
        "",
        "| corners from | grids found | ms per image (median) | mean distance to OpenCV's corners, "
        "max over images [px] | cv2.stereoCalibrate RMS [px] |",
        "|---|---|---|---|---|",
    ]
    names = {"ours": "ours (X-corners + HTM refinement)",
             "ours_eq10_quadric_only": "ours, the paper's eq. 10 quadric only",
             "opencv_sb": "cv2.findChessboardCornersSB"}
    for k, label in names.items():
        m = r.get(k)
        if not m:
            continue
        st = m.get("stereo_calibrate") or {}
        lines.append(f"| {label} | {m['grids_found']} of {m['images']} | {_f(m['ms_per_image_median'], 1)} | "
                     f"{_f(m.get('mean_dist_to_opencv_px_max'), 3)} | {_f(st.get('rms_px'), 3)} |")
    return lines


def render_virtual_lab(r: dict[str, Any]) -> list[str]:
    def med(lab: dict[str, Any], k: str) -> str:
        return _f(((lab.get("latency_ms") or {}).get(k) or {}).get("median_ms"), 1)

    lines = [
        "| image scale | cycle [s] | renderer alone / lab [fps] | capture -> command / transport / host after "
        "arrival / host's own work [ms, median] | cycles without a new frame / skipped | lab true tip mean / max "
        "[mm] | in process [mm] | lab / in process | the same at the lab's timing |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s in r.get("virtual_lab", []):
        lab = s.get("lab") or {}
        if "error" in lab:
            lines.append(f"| {s.get('image_scale')} | lab failed: {lab['error'][-200:]} |")
            continue
        ref = (s.get("in_process") or {}).get("true_tip_mm") or {}
        tt = lab.get("true_tip_mm") or {}
        tg = s.get("targets") or {}
        lines.append(
            f"| {s.get('image_scale')} | {_f(s.get('control_dt_s'))} | {_f((s.get('renderer') or {}).get('fps'), 1)}"
            f" / {_f(lab.get('fps_rendered'), 1)} | {med(lab, 'capture_to_command')} / {med(lab, 'transport')} / "
            f"{med(lab, 'arrival_to_command')} / {med(lab, 'arrival_to_ready')} | "
            f"{(lab.get('frames') or {}).get('cycles_without_a_new_frame', '-')} / {lab.get('cycles_skipped', '-')} | "
            f"{_f(tt.get('mean'), 3)} / {_f(tt.get('max'))} | {_f(ref.get('mean'), 3)} / {_f(ref.get('max'))} | "
            f"{_f(tg.get('true_tip_ratio'))} | {_f(tg.get('true_tip_ratio_latency_matched'))} |")
    lock = r.get("phase_lock") or {}
    cam = f"locked on the frames' {lock.get('on')} at {lock.get('lock_phase_s')} s" if lock else "free-running"
    return [*lines, "", f"Lab camera {cam}; real-time priority allowed: {r.get('realtime_priority')}; targets: "
            "lab / in process <= 1.2, host after a frame's arrival <= 10 ms (median)."]


def render_serial(r: dict[str, Any]) -> list[str]:
    lines = ["| request | median [us] | p99 [us] | max [us] |", "|---|---|---|---|"]
    for k, v in r.items():
        if isinstance(v, dict) and "median_us" in v:
            lines.append(f"| {k} | {_f(v['median_us'], 0)} | {_f(v.get('p99_us'), 0)} | {_f(v.get('max_us'), 0)} |")
    return lines


METRICS = ("open_mean_mm", "open_max_mm", "closed_mean_mm", "closed_max_mm", "ratio")


def load_sweep(folder: Path) -> dict[str, Any]:
    """results.csv of a sweep folder: the mean over each grid point's seeds."""
    with (folder / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    keys = ("latency", "plant.backlash.0")
    points: dict[tuple[str, ...], list[dict[str, str]]] = {}
    for row in rows:
        points.setdefault(tuple(row[k] for k in keys), []).append(row)
    out = []
    for key, rs in sorted(points.items(), key=lambda kv: tuple(float(x) for x in kv[0])):
        ok = [x for x in rs if x["status"] == "ok"]

        def mean(col: str, ok: list[dict[str, str]] = ok) -> float | None:
            return sum(float(x[col]) for x in ok) / len(ok) if ok else None

        out.append({"point": dict(zip(keys, key)), "trials": len(rs), "ok": len(ok),
                    **{c: mean(c) for c in METRICS}})
    return {"keys": list(keys), "points": out, "trials": len(rows)}


def render_sweep(r: dict[str, Any]) -> list[str]:
    lines = [
        f"{r['trials']} trials; each row the mean over its seeds.",
        "",
        "| latency [s] | plant.backlash.0 [rad] | trials ok | open mean / max [mm] | closed mean / max [mm] "
        "| closed / open |",
        "|---|---|---|---|---|---|",
    ]
    for p in r["points"]:
        lines.append(f"| {p['point']['latency']} | {p['point']['plant.backlash.0']} | {p['ok']} of {p['trials']} | "
                     f"{_f(p['open_mean_mm'])} / {_f(p['open_max_mm'])} | {_f(p['closed_mean_mm'], 3)} / "
                     f"{_f(p['closed_max_mm'], 3)} | {_f(100 * p['ratio'] if p['ratio'] is not None else None, 1)} % |")
    return lines


def render_several_arms(r: dict[str, Any]) -> list[str]:
    t = r.get("time_ms", {})
    same = ", on the scene's own background and noise" if r.get("alone_background") == "same" else ""
    lines = [
        f"{r['pairs']} rendered {r['image_size'][0]}x{r['image_size'][1]} stereo pairs of {len(r['arms'])} arms "
        f"({r['scene']}) in random poses, half the sequences crossing; each pair also rendered with each arm "
        f"alone (the one-arm figure{same}). Identity swaps: poses reported for an arm that lie nearer another arm's "
        f"truth: **{r['identity_swaps']}**; wrong (over 0.5 mm off): **{r['wrong']}** (the same arms alone: "
        f"{r.get('wrong_alone', '-')}).",
        "",
        "| arm | tracked together / alone | pairs with corners hidden by another arm | "
        "tip mean together / alone [mm] | tip max together / alone [mm] | "
        "tip mean together / alone where corners are hidden [mm] |",
        "|---|---|---|---|---|---|",
    ]
    for n, a in r["arms"].items():
        h = a.get("with_hidden_corners") or {}
        lines.append(f"| {n} | {a['tracked_together']} / {a['tracked_alone']} of {a['pairs']} | "
                     f"{a['pairs_with_hidden_corners']} | {_f(a['tip_mean_mm_together'], 3)} / "
                     f"{_f(a['tip_mean_mm_alone'], 3)} | {_f(a['tip_max_mm_together'], 3)} / "
                     f"{_f(a['tip_max_mm_alone'], 3)} | {_f(h.get('tip_mean_mm_together'), 3)} / "
                     f"{_f(h.get('tip_mean_mm_alone'), 3)} ({h.get('pairs', '-')} pairs) |")
    how = ("every arm but the first in a worker process of its own" if r.get("processes")
           else "the arms in threads as the arm set decides")
    return [*lines, "", f"Tracking time per pair (medians of this run; {how}): all sleeves together "
            f"{_f(t.get('together_median'), 1)} ms, one arm alone {_f(t.get('one_arm_median'), 1)} ms, ratio "
            f"{_f(t.get('ratio'))}."]


def render_scene_cube(r: dict[str, Any]) -> list[str]:
    lines = [
        f"Every arm walks its own {' x '.join(f'{1000 * v:.0f}' for v in r['cube_size_m'])} mm cube at once "
        f"({r['scene']}), open loop then closed loop, one camera, one tracking of all sleeves per frame; "
        f"controller `{r['controller']}`, {1000 * r['control_dt_s']:.0f} ms cycle, sensor {r['sensor']}.",
        "",
        "| arm | open loop mean / max [mm] | closed loop mean / max [mm] | closed / open | lost |",
        "|---|---|---|---|---|",
    ]
    for n, a in r["arms"].items():
        o, c = a["open_loop"], a["closed_loop"]
        lines.append(f"| {n} ({a['walk']}) | {_f(o['mean_mm'])} / {_f(o['max_mm'])} | {_f(c['mean_mm'], 3)} / "
                     f"{_f(c['max_mm'], 3)} | {_f(100 * a['ratio'], 1)} % | {c['lost']} |")
    cl = r["clearance"]
    return [*lines, "", f"Least distance between the arms' true bodies: {_f(cl['least_true_mm']['closed_loop'])} mm "
            f"closed loop (clearance {_f(cl['required_mm'], 1)} mm; open loop, which has no constraint, "
            f"{_f(cl['least_true_mm']['open_loop'])} mm). Tracking all sleeves in the loop: "
            f"{_f(r['tracking_ms_median'], 1)} ms per frame (median)."]


PY = ".venv/bin/python"
CODED_UNSEEN = ("--marker", "configs/marker_coded.yaml", "--orientation", "hold",
                "--plant", "configs/plant_unseen.yaml")

ENTRIES: tuple[Entry, ...] = (
    Entry("cube", "The cube on the simulated rig (make run's job)",
          ("wristmark", "experiment", "cube", "--no-progress", "--force", "--out", f"{OUT}/cube",
           "--json", f"{OUT}/cube.json"), 900, render_cube, json_file=f"{OUT}/cube.json"),
    Entry("cube_unseen", "The cube on the arm never used for tuning, coded sleeve, orientation held",
          ("wristmark", "experiment", "cube", *CODED_UNSEEN, "--seed", "0", "--no-progress", "--force",
           "--out", f"{OUT}/cube_unseen", "--json", f"{OUT}/cube_unseen.json"), 900, render_cube,
          json_file=f"{OUT}/cube_unseen.json"),
    Entry("cube_paper", "The cube with the paper's controller (eq. 17-21)",
          ("wristmark", "experiment", "cube", "--controller", "paper", "--no-progress", "--force",
           "--out", f"{OUT}/cube_paper", "--json", f"{OUT}/cube_paper.json"), 900, render_cube,
          json_file=f"{OUT}/cube_paper.json"),
    Entry("controllers", "Controller step time", (PY, "bench/controllers.py"), 300, render_controllers),
    Entry("backlash", "Closed loop against the size of the play",
          (PY, "bench/backlash_sweep.py", "--seeds", "0"), 600, render_backlash),
    Entry("accuracy", "Tip accuracy (paper IV.B)",
          ("wristmark", "experiment", "accuracy", "--no-progress", "--force", "--out", f"{OUT}/accuracy",
           "--json", f"{OUT}/accuracy.json"), 600, render_accuracy, json_file=f"{OUT}/accuracy.json"),
    Entry("tracking", "Stereo tracking of rendered 1080p pairs", (PY, "bench/tracking.py"), 600, render_tracking),
    Entry("kinematics", "Kinematics time", (PY, "bench/kinematics.py"), 300, render_kinematics),
    Entry("serial", "Protocol round trip over a pty", (PY, "bench/serial_latency.py"), 300, render_serial),
    Entry("virtual_lab", "The loop on the virtual lab (hardware path)",
          (PY, "bench/virtual_lab.py", "--skip-video", "--scales", "0.5"), 600, render_virtual_lab),
    Entry("virtual_lab_1080p", "The virtual lab at 1080p, both loops at the camera's rate",
          (PY, "bench/virtual_lab.py", "--skip-video", "--scales", "1.0", "--camera-matched", "--lab-share", "0.5"),
          600, render_virtual_lab),
    Entry("chessboard", "Calibration corners on real chessboard photographs",
          (PY, "bench/real_chessboard.py"), 300, render_chessboard),
    Entry("several_arms", "Several sleeves in one pair: two arms",
          (PY, "bench/several_arms.py", "--sequences", "20", "--pairs", "10", "--seed", "1", "--processes"), 600,
          render_several_arms),
    Entry("several_arms_three", "Several sleeves in one pair: three arms",
          (PY, "bench/several_arms.py", "--scene", "configs/scenes/three_arms.yaml", "--sequences", "20",
           "--pairs", "10", "--seed", "1", "--processes"), 900, render_several_arms),
    Entry("scene_cube", "Two arms each walking a cube in one view",
          ("wristmark", "experiment", "cube", "--scene", "configs/scenes/two_arms.yaml", "--no-progress", "--force",
           "--out", f"{OUT}/scene_cube", "--json", f"{OUT}/scene_cube.json"), 1800, render_scene_cube,
          json_file=f"{OUT}/scene_cube.json"),
    Entry("scene_cube_close", "Two arms whose cubes would collide",
          ("wristmark", "experiment", "cube", "--scene", "configs/scenes/two_arms_close.yaml", "--no-progress",
           "--force", "--out", f"{OUT}/scene_cube_close", "--json", f"{OUT}/scene_cube_close.json"), 1800,
          render_scene_cube, json_file=f"{OUT}/scene_cube_close.json"),
    Entry("sweep", "Closed loop against latency and stem backlash (a sweep)",
          ("wristmark", "sweep", "configs/sweeps/latency_backlash.yaml", "--out", f"{OUT}/sweep_latency_backlash",
           "--workers", "1", "--no-progress"), 900, render_sweep,
          json_file=f"{OUT}/sweep_latency_backlash", load=load_sweep, clean=f"{OUT}/sweep_latency_backlash"),
)
BY_NAME = {e.name: e for e in ENTRIES}


# ----------------------------------------------------------------------------- running


def _executable(argv: tuple[str, ...]) -> list[str]:
    """argv as written in the docs -> what to start: this interpreter, and its wristmark script."""
    head, rest = argv[0], list(argv[1:])
    if head == PY:
        return [sys.executable, *rest]
    if head == "wristmark":
        script = Path(sys.executable).with_name("wristmark")
        return [str(script), *rest] if script.exists() else [sys.executable, "-m", "wristmark", *rest]
    return list(argv)


def _commit() -> str:
    def git(*a: str) -> str:
        return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True).stdout.strip()

    rev = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", "wristmark", "bench", "configs")
    return rev + ("+local changes" if dirty else "")


def run_entry(e: Entry) -> bool:
    """Runs one command under its time limit; keeps runs/results/NAME.json and NAME.meta.json."""
    out = ROOT / OUT
    out.mkdir(parents=True, exist_ok=True)
    if e.clean:
        shutil.rmtree(ROOT / e.clean, ignore_errors=True)
    started = dt.datetime.now(dt.UTC)
    commit = _commit()  # the build measured: before the run (the tree may change while it runs)
    load0 = os.getloadavg()[0]
    t0 = time.monotonic()
    print(f"[{e.name}] {e.command}  (limit {e.timeout_s:.0f} s)", file=sys.stderr, flush=True)
    proc = subprocess.Popen(_executable(e.argv), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=e.timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGTERM)  # the command's own process group, nothing else
        try:
            proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
        print(f"[{e.name}] out of time after {e.timeout_s:.0f} s: block left as it was", file=sys.stderr)
        return False
    wall = time.monotonic() - t0
    (out / f"{e.name}.log").write_text(stderr)
    if proc.returncode != 0:
        print(f"[{e.name}] exit {proc.returncode} (stderr in {OUT}/{e.name}.log): block left as it was",
              file=sys.stderr)
        return False
    try:
        data = e.load(ROOT / e.json_file) if e.load and e.json_file else (
            json.loads((ROOT / e.json_file).read_text()) if e.json_file else json.loads(stdout))
    except (OSError, ValueError) as exc:
        print(f"[{e.name}] no JSON result ({exc}): block left as it was", file=sys.stderr)
        return False
    (out / f"{e.name}.json").write_text(json.dumps(data, indent=1, default=str))
    meta = {"command": e.command, "started_utc": started.strftime("%Y-%m-%d %H:%M"), "wall_s": round(wall, 1),
            "commit": commit, "cpus": os.cpu_count(), "load_start": round(load0, 1),
            "load_end": round(os.getloadavg()[0], 1)}
    (out / f"{e.name}.meta.json").write_text(json.dumps(meta, indent=1))
    print(f"[{e.name}] done in {wall:.0f} s", file=sys.stderr, flush=True)
    return True


def _stored(name: str) -> tuple[dict[str, Any], dict[str, Any]] | None:
    d, m = ROOT / OUT / f"{name}.json", ROOT / OUT / f"{name}.meta.json"
    if not (d.is_file() and m.is_file()):
        return None
    meta = json.loads(m.read_text())
    if meta.get("command") != BY_NAME[name].command:  # measured with another command: not this block's
        return None
    return json.loads(d.read_text()), meta


# ----------------------------------------------------------------------------- writing


def block_text(e: Entry, data: dict[str, Any], meta: dict[str, Any]) -> str:
    head = [
        f"Command: `{e.command}`",
        "",
        f"Measured {meta['started_utc']} UTC on {meta['commit']} ({meta['cpus']} cores, load "
        f"{meta['load_start']} -> {meta['load_end']}, {meta['wall_s']:.0f} s wall) by "
        f"`.venv/bin/python bench/results.py --only {e.name}`.",
        "",
    ]
    return "\n".join(head + e.render(data))


BLOCK = re.compile(r"(<!-- generated:(?P<name>[a-z_0-9]+):start -->\n)(?P<body>.*?)"
                   r"(\n<!-- generated:(?P=name):end -->)", re.S)


def rewrite_blocks(text: str, bodies: dict[str, str]) -> tuple[str, list[str]]:
    """Replaces the bodies of the named generated blocks; returns the text and the names done."""
    done: list[str] = []

    def sub(m: re.Match[str]) -> str:
        name = m.group("name")
        if name not in bodies:
            return m.group(0)
        done.append(name)
        return m.group(1) + bodies[name] + m.group(4)

    return BLOCK.sub(sub, text), done


def readme_table(stored: dict[str, tuple[dict[str, Any], dict[str, Any]]]) -> list[str] | None:
    """At most 6 rows beside the paper, every value written as in docs/results.md."""
    rows = []
    if "cube" in stored:
        s = cube_rows(stored["cube"][0])
        rows += [
            f"| cube (IV.C), open loop mean / max [mm] | {PAPER['open_mean']:.2f} / {PAPER['open_max']:.2f} | "
            f"{s['open']} | `make run` |",
            f"| cube, closed loop mean / max [mm] | {PAPER['closed_mean']:.2f} / {PAPER['closed_max']:.2f} | "
            f"{s['closed']} | `make run` |",
            f"| cube, closed / open | {PAPER['ratio_pct']:.1f} % | {s['ratio']} | `make run` |",
        ]
    if "cube_unseen" in stored:
        c = stored["cube_unseen"][0]
        rows.append("| cube, an arm never used for tuning (coded sleeve, orientation held), closed loop mean / max "
                    f"[mm] | - | {_mm(c['closed_loop'])} "
                    "| `bench/results.py --only cube_unseen` |")
    if "accuracy" in stored:
        a = stored["accuracy"][0]
        rows.append(f"| tip accuracy (IV.B), stereo vs optical tracker mean / max [mm] | "
                    f"{PAPER['accuracy_mean']:.2f} / {PAPER['accuracy_max']:.2f} | {_mm(a)} | "
                    "`wristmark experiment accuracy` |")
    if "tracking" in stored:
        o = stored["tracking"][0]["ours"]["paper"]
        rows.append(f"| image processing per stereo pair [ms] | about {PAPER['processing_ms']} | "
                    f"{_f(o['time_ms_roi_median'], 1)} tracking, {_f(o['time_ms_cold_median'], 1)} cold (median) | "
                    "`bench/tracking.py` |")
    if not rows:
        return None
    return ["| | paper | wristmark | command |", "|---|---|---|---|", *rows[:6]]


def rewrite_readme(text: str, table: list[str]) -> str:
    i, j = text.find(README_START), text.find(README_END)
    if i < 0 or j < i:
        raise SystemExit(f"README.md has no {README_START} ... {README_END} block")
    return text[: i + len(README_START)] + "\n" + "\n".join(table) + "\n" + text[j:]


def merged_table(old: str, table: list[str]) -> list[str]:
    """``table`` with the rows of the README's current table (``old``: the README) that it has no
    row for kept, in the current order: a row is known by its first cell (what it measures)."""
    i, j = old.find(README_START), old.find(README_END)
    current = [ln for ln in old[i + len(README_START):j].splitlines() if ln.startswith("|")] if 0 <= i < j else []

    def label(row: str) -> str:
        return row.split("|")[1].strip()

    new = {label(r): r for r in table[2:]}
    rows = [new.pop(label(r), r) for r in current[2:]] + list(new.values())  # current[:2]: header, rule
    return [*table[:2], *rows[:6]]


def write_docs(only: list[str] | None = None) -> None:
    """Rewrite docs/results.md's generated blocks, and the README's rows, from the results kept
    under runs/results/: only those of ``only`` when given (a block or row whose result was not
    run now keeps its text, even where an older result is kept)."""
    stored = {n: s for n in BY_NAME if (only is None or n in only) and (s := _stored(n)) is not None}
    bodies = {n: block_text(BY_NAME[n], *s) for n, s in stored.items()}
    text, done = rewrite_blocks(RESULTS_MD.read_text(), bodies)
    RESULTS_MD.write_text(text)
    missing = sorted(set(bodies) - set(done))
    print(f"docs/results.md: rewrote {', '.join(done) or 'no block'}"
          + (f"; no block for {', '.join(missing)}" if missing else ""), file=sys.stderr)
    table = readme_table(stored)
    if table is not None:
        readme = README.read_text()
        table = merged_table(readme, table)
        README.write_text(rewrite_readme(readme, table))
        print(f"README.md: results table, {len(table) - 2} rows", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", choices=sorted(BY_NAME), metavar="NAME",
                    help="run only this result (repeatable); see --list")
    ap.add_argument("--list", action="store_true", help="print the names, time limits and commands, run nothing")
    ap.add_argument("--collect-only", action="store_true",
                    help="run nothing: rewrite every block of the docs from the results kept under runs/results/ "
                         "(with --only: the docs' blocks of those results only)")
    a = ap.parse_args(argv)
    if a.list:
        for e in ENTRIES:
            print(f"{e.name:12s} {e.timeout_s:5.0f} s  {e.command}")
        return 0
    failed = []
    if not a.collect_only:
        for e in ENTRIES:
            if (a.only is None or e.name in a.only) and not run_entry(e):
                failed.append(e.name)
    write_docs(a.only)
    if failed:
        print(f"not regenerated: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
