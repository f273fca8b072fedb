"""Matplotlib figures of a sweep (PNG, headless): each metric against a swept key, and a heat
map of a metric over two swept keys. Rows are results.csv rows (strings); only rows whose
status is ``ok`` are drawn."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure  # no pyplot: the process's matplotlib backend is left alone

Row = dict[str, str]


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def axis_values(rows: Sequence[Row], key: str) -> tuple[list[str], bool]:
    """The distinct values of ``key`` in order (numeric: sorted by value) and whether numeric."""
    distinct = list(dict.fromkeys(r[key] for r in rows))
    numeric = all(_number(v) is not None for v in distinct)
    if numeric:
        distinct.sort(key=lambda v: float(v))
    return distinct, numeric


def ok_rows(rows: Sequence[Row]) -> list[Row]:
    """The rows of trials that finished (status ok)."""
    return [r for r in rows if r["status"] == "ok"]


def plot_metrics_vs_key(rows: Sequence[Row], key: str, metrics: Sequence[tuple[str, str]], path: Path) -> Path:
    """One panel per (metric column, label): every ok trial against ``key``, and the mean per value."""
    good = ok_rows(rows)
    values, numeric = axis_values(rows, key)
    pos = {v: (float(v) if numeric else i) for i, v in enumerate(values)}
    fig = Figure(figsize=(3.6 * len(metrics), 3.2))
    axes = fig.subplots(1, len(metrics), squeeze=False)
    for ax, (col, label) in zip(axes[0], metrics):
        x = np.array([pos[r[key]] for r in good], float)
        y = np.array([float(r[col]) for r in good], float)
        ax.plot(x, y, "o", ms=4, alpha=0.45, color="tab:blue", label="trials")
        xs = [pos[v] for v in values if any(r[key] == v for r in good)]
        ms = [np.mean([float(r[col]) for r in good if r[key] == v]) for v in values if any(r[key] == v for r in good)]
        ax.plot(xs, ms, "-", color="tab:red", lw=1.5, label="mean")
        ax.set_xlabel(key)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if not numeric:
            ax.set_xticks(range(len(values)), values, rotation=30, fontsize=8)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"metrics against {key} ({len(good)} ok trials)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


def plot_heatmap(rows: Sequence[Row], kx: str, ky: str, metrics: Sequence[tuple[str, str]], path: Path) -> Path:
    """One heat map per (metric, label): the mean over ok trials in each cell (kx, ky)."""
    good = ok_rows(rows)
    xs, _ = axis_values(rows, kx)
    ys, _ = axis_values(rows, ky)
    fig = Figure(figsize=(4.6 * len(metrics), 3.8))
    axes = fig.subplots(1, len(metrics), squeeze=False)
    for ax, (col, label) in zip(axes[0], metrics):
        grid = np.full((len(ys), len(xs)), np.nan)
        for i, vy in enumerate(ys):
            for j, vx in enumerate(xs):
                cell = [float(r[col]) for r in good if r[kx] == vx and r[ky] == vy]
                if cell:
                    grid[i, j] = np.mean(cell)
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        lo, hi = (np.nanmin(grid), np.nanmax(grid)) if np.isfinite(grid).any() else (0.0, 1.0)
        for i in range(len(ys)):
            for j in range(len(xs)):
                if np.isfinite(grid[i, j]):
                    light = hi > lo and (grid[i, j] - lo) / (hi - lo) > 0.6  # viridis turns yellow
                    ax.text(j, i, f"{grid[i, j]:.3g}", ha="center", va="center", fontsize=8,
                            color="black" if light else "white")
        ax.set_xticks(range(len(xs)), xs, rotation=30, fontsize=8)
        ax.set_yticks(range(len(ys)), ys, fontsize=8)
        ax.set_xlabel(kx)
        ax.set_ylabel(ky)
        ax.set_title(label, fontsize=10)
        fig.colorbar(im, ax=ax, shrink=0.85)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path
