"""The play (backlash) of one actuator fitted from a probe: encoder readings against the arm.

A probe (rig/loop/play_probe.py) moves one actuator's motor back and forth through more than its
largest play while the others are held, and records per cycle the motor position m_k (the
encoders, at the frame's capture) and the arm-side value y_k of the same actuator (the tracker's
6-DoF tip pose through the nominal pose IK and actuation map). Assumed: between the motor and the
arm sits a play operator of width b (output o_k = clip(o_{k-1}, m_k - b/2, m_k + b/2), the
motor monotonic between two samples), and the arm-side value is affine in the output near the
probed configuration, y_k = c + g o_k + noise: the arm's gain and offset errors as the nominal
model sees them enter only as g and c, and the other actuators, held, only as c.

The fit is the least-squares fit of that model to every sample: for each b on a grid in
[0, play_max] and each starting place of the output in its band (unknown: the probe starts
wherever the settle left the arm), the operator is run through the readings and (c, g) follow by
linear least squares; the pair with the smallest residual wins. Using every sample, including the
ones inside the band where the arm stands still, is what makes a short probe enough (a fit on the
dragged samples alone, y = c + g m + h s, loses most of them to the motor's lag at the turns).
The fit also gives the output at the last sample, so the dead-band inversion can start on a known
side and place instead of the middle of the band.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

Array = NDArray[np.float64]

PLAY_STEPS = 81  # grid of the play over [0, play_max]
MIN_GAIN = 0.3  # a fitted gain below this (or above its inverse) is refused: the probe did not move the arm
MAX_NOISE = 0.1  # a residual (in motor units) above this x play_max is refused: the pose is too noisy for it
START_STEPS = 17  # grid of the output's starting place in its band

@dataclass(frozen=True)
class PlayFit:
    """One actuator's probe fit: play b [rad or m], gain g and offset c of the arm-side value on
    the output, the output's last position [rad or m, motor units] and the residual RMS [y units];
    ``ok`` False when the fit is not to be trusted (too few samples, gain out of range, the probe
    did not travel past play_max; with too few samples or travel the numbers are 0, the outputs
    the last reading)."""

    play: float
    gain: float
    offset: float
    first_output: float
    last_output: float
    residual_rms: float
    ok: bool
    motor_tau: float = float("nan")  # the motor's first-order lag [s] fitted from the encoders (NaN: none)


def play_operator(motor: Array, plays: Array, starts: Array) -> Array:
    """Outputs (n_plays, n_starts, n_samples) of play operators of widths ``plays`` whose output
    starts at m_0 - start x b / 2, driven by the motor samples ``motor``."""
    m = np.asarray(motor, float)
    half = 0.5 * np.asarray(plays, float)[:, None]
    out = np.empty((len(plays), len(starts), m.size))
    o = m[0] - np.asarray(starts, float)[None, :] * half
    for k, mk in enumerate(m):
        o = np.clip(o, mk - half, mk + half)
        out[:, :, k] = o
    return out


def fit_play(motor: Array, arm: Array, play_max: float, min_samples: int = 6, refine: bool = True) -> PlayFit:
    """Fit y = c + g o(m; b) to the probe's motor readings ``motor`` and arm-side values ``arm``
    (same units, one per cycle); b within [0, ``play_max``]: the best of a grid of plays and
    starts, then (``refine``) refined continuously (~50 x the grid's time)."""
    m = np.asarray(motor, float)
    y = np.asarray(arm, float)
    keep = np.isfinite(m) & np.isfinite(y)
    m, y = m[keep], y[keep]
    if m.size < min_samples or play_max <= 0.0 or np.ptp(m) <= play_max:
        at = float(m[-1]) if m.size else 0.0
        return PlayFit(0.0, 0.0, 0.0, at, at, 0.0, False)
    plays = np.linspace(0.0, play_max, PLAY_STEPS)
    starts = np.linspace(-1.0, 1.0, START_STEPS)
    o = play_operator(m, plays, starts)  # (P, S, K)
    om = o.mean(axis=2, keepdims=True)
    ym = y.mean()
    do = o - om
    var = np.sum(do * do, axis=2)
    cov = np.sum(do * (y - ym), axis=2)
    g = np.where(var > 0, cov / np.where(var > 0, var, 1.0), 0.0)
    resid = np.sum((y - ym) ** 2) - g * cov  # residual sum of squares per (b, start)
    i, j = np.unravel_index(int(np.argmin(resid)), resid.shape)
    b, start = float(plays[i]), float(starts[j])
    if refine:
        b, start = _refine(m, y, b, start, play_max)
    o1 = play_operator(m, np.array([b]), np.array([start]))[0, 0]
    gain, c, rss = _line(o1, y)
    rms = float(np.sqrt(max(rss, 0.0) / m.size))
    ok = MIN_GAIN <= gain <= 1.0 / MIN_GAIN and rms / gain <= MAX_NOISE * play_max
    return PlayFit(b, gain, c, float(o1[0]), float(o1[-1]), rms, bool(ok))


def fused_readout(motor: Array, readouts: Sequence[Array], play_max: float) -> Array:
    """One arm-side series [motor units] from several readouts of the same output, one value per
    sample each (NaN: not read), every one affine in the output with its own noise (the tip's
    position and its rotation along the motion an actuator causes: rig/loop/play_probe.py's
    TipProjection): each is fitted alone (:func:`fit_play` on its grid), put in motor units, (y - c) / g, and
    the samples averaged with weights 1 / (its residual RMS / g)^2 over the readouts that read
    them. A readout whose fit has too few samples or a gain out of [MIN_GAIN, 1 / MIN_GAIN] (the
    output does not move it) is left out; where none is kept, the first, as it was."""
    m = np.asarray(motor, float)
    ys = [np.asarray(y, float) for y in readouts]
    num, den = np.zeros(m.size), np.zeros(m.size)
    for y in ys:
        f = fit_play(m, y, play_max, refine=False)  # a weight needs no refined play
        if not (f.gain > 0 and MIN_GAIN <= f.gain <= 1.0 / MIN_GAIN and f.residual_rms > 0):
            continue
        w = (f.gain / f.residual_rms) ** 2
        read = np.isfinite(y) & np.isfinite(m)
        num[read] += w * (y[read] - f.offset) / f.gain
        den[read] += w
    if not np.any(den > 0):
        return ys[0]
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)


def _line(o: Array, y: Array) -> tuple[float, float, float]:
    """Least-squares y = c + g o: (g, c, residual sum of squares)."""
    do, dy = o - o.mean(), y - y.mean()
    var = float(do @ do)
    g = float(do @ dy) / var if var > 0 else 0.0
    return g, float(y.mean() - g * o.mean()), float(dy @ dy - g * (do @ dy))


def _path_rss(motor: list[float], arm: list[float], sy: float, syy: float, play: float, start: float) -> float:
    """The residual sum of squares of the line y = c + g o through the outputs o of one play
    operator (:func:`play_operator` for one ``play`` and one ``start``), as :func:`_line`; on
    Python floats, ``arm`` about its mean (``sy``, ``syy``: its sum and sum of squares, the
    caller's once) and the outputs about the motor's first sample (the refinement runs it some
    200 times: on arrays their overheads made a fit 25 ms, 12 here)."""
    half = 0.5 * play
    m0 = motor[0]
    o = -start * half
    n = len(motor)
    so = soo = soy = 0.0
    for mk, yk in zip(motor, arm):
        o = min(max(o, mk - m0 - half), mk - m0 + half)
        so += o
        soo += o * o
        soy += o * yk
    var = soo - so * so / n
    cov = soy - so * sy / n
    return syy - cov * cov / var if var > 0 else syy


def _refine(m: Array, y: Array, b0: float, s0: float, play_max: float) -> tuple[float, float]:
    """The grid's best (play, start) refined continuously (Nelder-Mead, within the bounds), so
    that a small change of the readings (a micro-unit rounding) moves the fit a little, never by
    a grid step."""
    motor = [float(v) for v in m]
    arm = [float(v) for v in y - y.mean()]
    sy, syy = sum(arm), sum(v * v for v in arm)

    def rss(x: Array) -> float:
        return _path_rss(motor, arm, sy, syy, min(max(float(x[0]), 0.0), play_max), min(max(float(x[1]), -1.0), 1.0))

    step = play_max / (PLAY_STEPS - 1)
    simplex = np.array([[b0, s0], [b0 + step, s0], [b0, s0 + 2.0 / (START_STEPS - 1)]])
    res = minimize(rss, np.array([b0, s0]), method="Nelder-Mead",
                   options={"initial_simplex": simplex, "xatol": 1e-3 * step, "fatol": 0.0, "maxiter": 400})
    best = res.x if res.fun <= rss(np.array([b0, s0])) else np.array([b0, s0])
    return float(np.clip(best[0], 0.0, play_max)), float(np.clip(best[1], -1.0, 1.0))


TAU_GRID = np.geomspace(0.002, 0.4, 161)  # motor lags tried [s] (ratio 1.033 a step)
MAX_LAG_RESIDUAL = 0.05  # a lag fit whose RMS exceeds this x the commands' span is refused


def first_order_response(m0: float, sends: Array, targets: Array, times: Array, tau: float) -> Array:
    """The positions at ``times`` of a first-order motor of lag ``tau`` [s] that starts at ``m0``
    at ``times[0]`` and follows the targets ``targets`` sent at ``sends`` (held between sends;
    the target before the first send is ``m0``)."""
    events = sorted([(float(t), 1, float(u)) for t, u in zip(sends, targets)] +
                    [(float(t), 0, 0.0) for t in times])  # at equal times the reading comes first
    m, u, t_last = float(m0), float(m0), float(times[0])
    out = []
    for t, kind, val in events:
        if t < t_last:
            continue
        m = u + (m - u) * (np.exp(-(t - t_last) / tau) if tau > 0 else 0.0)
        t_last = t
        if kind == 1:
            u = val
        else:
            out.append(m)
    return np.asarray(out, float)


def fit_motor_lag(sends: Array, targets: Array, times: Array, motor: Array) -> float:
    """The first-order lag tau [s] of a motor from its targets ``targets`` sent at ``sends`` [s]
    and its encoder readings ``motor`` at ``times`` [s] (same clock, same units; the first reading
    before the first send): the least-squares tau on a log grid over [2 ms, 0.4 s]. NaN when the
    targets hardly move or the model does not fit (RMS above MAX_LAG_RESIDUAL x their span)."""
    ts, m = np.asarray(times, float), np.asarray(motor, float)
    s, u = np.asarray(sends, float), np.asarray(targets, float)
    keep = np.isfinite(ts) & np.isfinite(m)
    ts, m = ts[keep], m[keep]
    if m.size < 4 or s.size < 2:
        return float("nan")
    span = float(np.ptp(np.concatenate([u, m[:1]])))
    if span <= 0.0:
        return float("nan")
    rss = np.array([float(np.sum((first_order_response(m[0], s, u, ts, tau) - m) ** 2)) for tau in TAU_GRID])
    k = int(np.argmin(rss))
    if np.sqrt(rss[k] / m.size) > MAX_LAG_RESIDUAL * span:
        return float("nan")
    if 0 < k < TAU_GRID.size - 1:  # a parabola through the three best, in log tau
        y0, y1, y2 = rss[k - 1], rss[k], rss[k + 1]
        den = y0 - 2 * y1 + y2
        shift = 0.5 * (y0 - y2) / den if den > 0 else 0.0
        return float(TAU_GRID[k] * (TAU_GRID[k + 1] / TAU_GRID[k]) ** float(np.clip(shift, -0.5, 0.5)))
    return float(TAU_GRID[k])
