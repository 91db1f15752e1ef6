"""A campaign's box-and-whisker plots and Markdown report."""

from __future__ import annotations

import datetime
import math
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

# One colour per method, in the study's order (colour-blind safe).
_COLORS = ["#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9"]


def _Values(rows, family, humans, method, metric):
    out = []
    for r in rows:
        if (
            r.get("status") == "ok"
            and r["family"] == family
            and r["humans"] == humans
            and r["method"] == method
        ):
            v = r.get(metric, math.nan)
            v = float(v) if not isinstance(v, str) else math.nan
            if not math.isnan(v):
                out.append(v)
    return out


def MakePlots(study, rows, out_dir) -> list[Path]:
    """Writes ``<study>.png``: one panel per Study.panels entry, the number
    of humans on the x axis, one box per method (median line, mean ×),
    laid out like the paper's figures. Returns the written files."""

    matplotlib.use("Agg")

    panels = study.panels
    ncols = min(4, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(3.4 * ncols, 3.0 * nrows), squeeze=False
    )
    methods = [m.name for m in study.methods]
    width = 0.8 / len(methods)
    for ax, panel in zip(axes.flat, panels, strict=False):
        humans = sorted({c.humans for c in study.cells if c.family == panel.family})
        for j, method in enumerate(methods):
            data, positions = [], []
            for i, h in enumerate(humans):
                values = _Values(rows, panel.family, h, method, panel.metric)
                if values:
                    data.append(values)
                    positions.append(i + (j - (len(methods) - 1) / 2) * width)
            if not data:
                continue
            color = _COLORS[j % len(_COLORS)]
            ax.boxplot(
                data,
                positions=positions,
                widths=0.9 * width,
                patch_artist=True,
                showmeans=True,
                meanprops=dict(marker="x", markeredgecolor="black", markersize=6),
                medianprops=dict(color="black"),
                boxprops=dict(facecolor=color, alpha=0.75),
                flierprops=dict(marker=".", markersize=4),
                manage_ticks=False,
            )
        ax.set_xticks(range(len(humans)))
        ax.set_xticklabels([f"{h} human{'s' if h > 1 else ''}" for h in humans])
        ax.set_title(panel.title, fontsize=9)
        ax.set_ylabel(panel.ylabel)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis("off")
    handles = [
        plt.Rectangle((0, 0), 1, 1, color=_COLORS[j % len(_COLORS)], alpha=0.75)
        for j in range(len(methods))
    ]
    fig.legend(handles, methods, loc="lower center", ncol=len(methods), frameon=False)
    fig.suptitle(f"{study.name}: median (line), mean (×)", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    path = Path(out_dir) / f"{study.name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [path]


def _Stat(values) -> str:
    if not values:
        return "–"
    return f"{np.median(values):.3g} ({np.mean(values):.3g})"


def _Rate(rows, key) -> str:
    values = [r.get(key) for r in rows if isinstance(r.get(key), bool)]
    if not values:
        return "–"
    return f"{sum(values)}/{len(values)}"


def WriteReport(study, rows, out_dir, plots, *, wall_time_s: float, ran: int) -> Path:
    """Writes ``<study>_report.md``: the panels' tables (median (mean) per
    number of humans and method) and a per-cell summary."""
    methods = [m.name for m in study.methods]
    ok = [r for r in rows if r.get("status") == "ok"]
    failed = [r for r in rows if r.get("status") != "ok"]
    busy = sum(float(r.get("wall_time_s") or 0.0) for r in rows)
    lines = [
        f"# Study `{study.name}`",
        "",
        study.description,
        "",
        f"- Runs in the CSV: {len(rows)} ({len(ok)} completed, {len(failed)} "
        f"failed to run), {busy / 60:.1f} min of run time in all; this "
        f"invocation ran {ran} in {wall_time_s / 60:.1f} min of wall time.",
        f"- Written {datetime.datetime.now().isoformat(timespec='seconds')}; "
        f"replay any run with `sm2ith replay {study.name}.csv ROW`.",
        "",
    ]
    for plot in plots:
        lines += [f"![{study.name}]({Path(plot).name})", ""]
    lines += ["## Panels: median (mean) over the seeds", ""]
    for panel in study.panels:
        humans = sorted({c.humans for c in study.cells if c.family == panel.family})
        lines += [
            f"### {panel.title} [{panel.ylabel}]",
            "",
            "| humans | " + " | ".join(methods) + " |",
            "|---|" + "---|" * len(methods),
        ]
        for h in humans:
            cells = [
                _Stat(_Values(ok, panel.family, h, m, panel.metric)) for m in methods
            ]
            lines.append(f"| {h} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "## Per scenario and method",
        "",
        "Booleans are counts over the runs; numbers are median (mean).",
        "",
        "| scenario | method | runs | " + " | ".join(study.summary) + " |",
        "|---|---|---|" + "---|" * len(study.summary),
    ]
    for cell in study.cells:
        for method in methods:
            group = [
                r
                for r in ok
                if r["scenario"] == cell.scenario and r["method"] == method
            ]
            if not group:
                continue
            stats = []
            for key in study.summary:
                if key in ("success", "collision"):
                    stats.append(_Rate(group, key))
                else:
                    values = [
                        float(r[key])
                        for r in group
                        if not isinstance(r.get(key), str)
                        and not math.isnan(float(r.get(key, math.nan)))
                    ]
                    stats.append(_Stat(values))
            lines.append(
                f"| {cell.scenario} | {method} | {len(group)} | "
                + " | ".join(stats)
                + " |"
            )
    if failed:
        lines += ["", "## Runs that failed to run", ""]
        lines += [f"- {r['run_id']}: {r.get('error', '')}" for r in failed]
    path = Path(out_dir) / f"{study.name}_report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
