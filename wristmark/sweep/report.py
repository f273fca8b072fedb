"""``DIR/summary.md`` of a sweep: what ran, a table of the metrics per swept point (the mean
over its seeds and ok trials), the failed trials, and plots (``DIR/plots/``): each metric against
each swept key, and a heat map over the first two grid keys."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from wristmark.sweep.keys import format_value
from wristmark.sweep.spec import SweepSpec

Row = dict[str, str]
LOOP_METRICS = (("open_mean_mm", "open mean [mm]"), ("open_max_mm", "open max [mm]"),
                ("closed_mean_mm", "closed mean [mm]"), ("closed_max_mm", "closed max [mm]"),
                ("ratio", "closed/open"))
ACCURACY_METRICS = (("accuracy_mean_mm", "accuracy mean [mm]"), ("accuracy_max_mm", "accuracy max [mm]"))


def table_metrics(experiment: str) -> tuple[tuple[str, str], ...]:
    """(column, label) of the metrics a summary shows for ``experiment``."""
    return ACCURACY_METRICS if experiment == "accuracy" else LOOP_METRICS


def _slug(key: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", key).strip("_")


def _fmt(col: str, values: list[float]) -> str:
    if not values:
        return "—"
    m = float(np.mean(values))
    text = f"{100 * m:.1f} %" if col == "ratio" else f"{m:.3f}"
    if len(values) > 1 and col == "closed_mean_mm":
        text += f" ± {float(np.std(values, ddof=1)):.3f}"
    return text


def summary_table(spec: SweepSpec, rows: Sequence[Row]) -> str:
    """Markdown table: one line per swept point (grid x random), metrics averaged over its ok trials."""
    keys = spec.swept_keys
    metrics = table_metrics(spec.experiment)
    groups: dict[tuple[str, ...], list[Row]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in keys), []).append(r)
    head = [*keys, "trials", "ok", *(label for _, label in metrics)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for point, members in groups.items():
        good = [r for r in members if r["status"] == "ok"]
        cells = [*point, str(len(members)), str(len(good))]
        cells += [_fmt(col, [float(r[col]) for r in good]) for col, _ in metrics]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_plots(spec: SweepSpec, out: Path, rows: Sequence[Row]) -> list[Path]:
    """The PNGs of a sweep in ``out/plots`` (none when no trial finished)."""
    from wristmark.viz.sweep_plots import ok_rows, plot_heatmap, plot_metrics_vs_key

    if not ok_rows(rows):
        return []
    folder = out / "plots"
    folder.mkdir(exist_ok=True)
    metrics = table_metrics(spec.experiment)
    paths = [plot_metrics_vs_key(rows, k, metrics, folder / f"metrics_vs_{_slug(k)}.png") for k in spec.swept_keys]
    grid = list(spec.grid)
    if len(grid) >= 2:
        heat = [metrics[2], metrics[4]] if spec.experiment != "accuracy" else list(metrics)
        paths.append(plot_heatmap(rows, grid[0], grid[1], heat,
                                  folder / f"heatmap_{_slug(grid[0])}_{_slug(grid[1])}.png"))
    return paths


def write_summary(spec: SweepSpec, out: Path, rows: Sequence[Row], shown_out: Path | None = None) -> str:
    """Write ``out/summary.md`` (and the plots); return the table. ``shown_out``: the folder as
    the command line named it."""
    table = summary_table(spec, rows)
    plots = write_plots(spec, out, rows)
    failed = [r for r in rows if r["status"] != "ok"]
    walls = [float(r["wall_s"]) for r in rows if r["wall_s"] not in ("", "nan")]
    fixed = ", ".join(f"{k}={format_value(v)}" for k, v in spec.fixed.items()) or "none"
    md = [
        f"# Sweep: {spec.experiment}, {len(rows)} of {len(spec.trials)} trials",
        "",
        f"Command: `wristmark sweep {spec.path} --out {shown_out or out}`",
        "",
        f"Fixed options: {fixed}. Swept: {', '.join(spec.swept_keys) or 'seeds only'}; "
        f"seeds: {', '.join(map(str, spec.seeds))}"
        + (f"; {spec.random_n} random samples (seed {spec.random_seed})" if spec.random_n else "") + ".",
        f"Trials ok: {len(rows) - len(failed)}, failed: {len(failed)}; trial wall time median "
        f"{np.median(walls) if walls else float('nan'):.1f} s, total {sum(walls):.0f} s (summed over workers).",
        "",
        "Errors are the optical tracker's tip against the desired tip. Each line: the mean over the "
        "line's ok trials (its seeds" + (" and random samples" if spec.random_n and spec.grid else "")
        + "); ± is the standard deviation over them. Every trial: results.csv.",
        "",
        table,
    ]
    if failed:
        md += ["## Failed trials", "", "| trial | status |", "|---|---|"]
        md += [f"| {r['trial']} | {r['status'].replace('|', '/')} |" for r in failed]
        md.append("")
    if plots:
        md += ["## Plots", ""] + [f"![{p.stem}](plots/{p.name})" for p in plots] + [""]
    (out / "summary.md").write_text("\n".join(md) + "\n")
    return table
