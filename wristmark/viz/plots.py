"""Matplotlib figures of the experiments (PNG, headless): paper Fig. 7(c) and Fig. 8 look-alikes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure  # no pyplot: the process's matplotlib backend is left alone

from wristmark.rig.loop.metrics import tracking_errors
from wristmark.rig.recording.run_log import RunLog


def plot_cube(log: RunLog, out_dir: Path) -> list[Path]:
    """3D paths (desired, open-loop true, closed-loop true) and error over time [mm]."""
    out_dir = Path(out_dir)
    paths = []
    fig = Figure(figsize=(11, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    styles = {"open_loop": ("tab:red", "open loop"), "closed_loop": ("tab:blue", "closed loop")}
    des_drawn = False
    for phase, (col, label) in styles.items():
        recs = log.phase(phase)
        if not recs:
            continue
        P = 1000 * np.array([r.p_trk for r in recs])
        D = 1000 * np.array([r.p_des for r in recs])
        if not des_drawn:
            ax.plot(D[:, 0], D[:, 1], D[:, 2], "k--", lw=1.2, label="desired")
            des_drawn = True
        ax.plot(P[:, 0], P[:, 1], P[:, 2], color=col, lw=1.0, label=label)
    ax.set_xlabel("x_w [mm]")
    ax.set_ylabel("y_w [mm]")
    ax.set_zlabel("z_w [mm]")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("Tip paths (optical tracker)")
    ax2 = fig.add_subplot(1, 2, 2)
    for phase, (col, label) in styles.items():
        recs = log.phase(phase)
        if not recs:
            continue
        t = np.array([r.t for r in recs])
        e = 1000 * tracking_errors(recs, "p_trk")
        ax2.plot(t - t[0], e, color=col, lw=1.0, label=f"{label}: mean {np.nanmean(e):.2f} mm")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("tip error [mm]")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8)
    ax2.set_title("Tip error vs desired")
    # fixed margins: tight_layout measures the 3D axes' every label (a second per figure here)
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.1, top=0.92, wspace=0.15)
    p = out_dir / "cube.png"
    fig.savefig(p, dpi=110)
    paths.append(p)
    return paths


def plot_accuracy(rows: list[dict[str, Any]], out_dir: Path) -> Path:
    """Estimated vs tracker tip per position, and the distance error [mm] (like Fig. 7(c))."""
    out_dir = Path(out_dir)
    ok = [r for r in rows if r["ok"]]
    fig = Figure(figsize=(11, 4.5))
    axes = fig.subplots(1, 2)
    if ok:
        T = 1000 * np.array([r["tracker"] for r in ok])
        E = 1000 * np.array([r["estimate"] for r in ok])
        idx = [r["index"] for r in ok]
        for k, (name, col) in enumerate(zip("xyz", ("tab:red", "tab:green", "tab:blue"))):
            axes[0].plot(idx, T[:, k], "o", color=col, ms=4, mfc="none", label=f"{name} tracker")
            axes[0].plot(idx, E[:, k], "x", color=col, ms=4, label=f"{name} stereo")
        axes[1].bar(idx, [r["error_mm"] for r in ok], color="tab:purple")
    axes[0].set_xlabel("position #")
    axes[0].set_ylabel("tip coordinate in {w} [mm]")
    axes[0].legend(fontsize=7, ncol=3)
    axes[1].set_xlabel("position #")
    axes[1].set_ylabel("|stereo - tracker| [mm]")
    axes[1].grid(alpha=0.3)
    fig.tight_layout()
    p = out_dir / "accuracy.png"
    fig.savefig(p, dpi=110)
    return p
