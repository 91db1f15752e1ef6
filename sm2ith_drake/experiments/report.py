"""A campaign's box-and-whisker plots and Markdown report: per safety
variant and people model, the paper's panels with the medians' 95 % CIs,
paired differences between methods, and the "what holds" table."""

from __future__ import annotations

import datetime
import math
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from sm2ith_drake.experiments.findings import (
    CONTACT_FREE_SUCCESS,
    Axes,
    Difference,
    FindingRows,
    Median,
    Select,
    Value,
    WhatHoldsTable,
)
from sm2ith_drake.experiments.statistics import MedianCI
from sm2ith_drake.run.metrics import BOOLEAN_METRICS

# One colour per method, in the study's order (colour-blind safe), and the
# colour of the medians' CI bars.
_COLORS = ["#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9"]
_CI_COLOR = "#D55E00"
_BOOLEAN = (*BOOLEAN_METRICS, CONTACT_FREE_SUCCESS)


def _Values(rows, family, humans, method, metric):
    group = Select(rows, family=family, humans=(humans,), method=method)
    values = [Value(r, metric) for r in group]
    return [v for v in values if not math.isnan(v)]


def _Humans(study, family):
    return sorted({c.humans for c in study.cells if c.family == family})


def _Tag(variant, people) -> str:
    return f"{variant}_{people}"


def _Plot(study, rows, path: Path, title: str) -> None:
    """The study's panels (number of humans on the x axis, one box per
    method: median line, mean ×, grey whiskers) with each median's 95 % CI
    as a red bar with caps, laid out like the paper's figures."""
    panels = study.panels
    ncols = min(4, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(3.4 * ncols, 3.0 * nrows), squeeze=False
    )
    methods = [m.name for m in study.methods]
    width = 0.8 / len(methods)
    for ax, panel in zip(axes.flat, panels, strict=False):
        humans = _Humans(study, panel.family)
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
                whiskerprops=dict(color="0.5"),
                capprops=dict(color="0.5"),
                manage_ticks=False,
            )
            for x, values in zip(positions, data, strict=True):
                m = MedianCI(values)
                if m.n >= 2 and not math.isnan(m.low):
                    ax.errorbar(
                        x,
                        m.value,
                        yerr=[[m.value - m.low], [m.high - m.value]],
                        fmt="none",
                        ecolor=_CI_COLOR,
                        elinewidth=2.0,
                        capsize=3,
                        zorder=5,
                    )
        if not ax.has_data():
            ax.text(0.5, 0.5, "no runs", ha="center", transform=ax.transAxes)
        ax.set_xticks(range(len(humans)))
        ax.set_xticklabels(
            [f"{h} human{'s' if h > 1 else ''}" for h in humans], fontsize=8
        )
        ax.set_title(panel.title, fontsize=9)
        ax.set_ylabel(panel.ylabel)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis("off")
    handles = [
        plt.Rectangle((0, 0), 1, 1, color=_COLORS[j % len(_COLORS)], alpha=0.75)
        for j in range(len(methods))
    ]
    handles.append(plt.Line2D([0], [0], color=_CI_COLOR, linewidth=2.0))
    labels = methods + ["95 % CI of the median"]
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), frameon=False)
    fig.suptitle(f"{title}: median (line), mean (×)", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def MakePlots(study, rows, out_dir) -> list[Path]:
    """Writes ``<study>_<variant>_<people>.png`` for every variant and
    people model in the rows. Returns the written files."""
    matplotlib.use("Agg")
    paths = []
    for variant, people in Axes(rows):
        group = Select(rows, variant=variant, people=people)
        path = Path(out_dir) / f"{study.name}_{_Tag(variant, people)}.png"
        _Plot(study, group, path, f"{study.name} ({variant}, {people} people)")
        paths.append(path)
    return paths


def _Rate(rows, key) -> str:
    values = [Value(r, key) for r in rows]
    values = [v for v in values if not math.isnan(v)]
    if not values:
        return "–"
    return f"{int(sum(values))}/{len(values)}"


def _PanelTable(study, rows, panel) -> list[str]:
    """Median [95 % CI] per number of humans and method, and each other
    method's mean paired difference to the first [95 % CI]."""
    methods = [m.name for m in study.methods]
    first, others = methods[0], methods[1:]
    header = methods + [f"{o} − {first}" for o in others]
    lines = [
        f"#### {panel.title} [{panel.ylabel}]",
        "",
        "| humans | " + " | ".join(header) + " |",
        "|---|" + "---|" * len(header),
    ]
    for h in _Humans(study, panel.family):
        group = Select(rows, family=panel.family, humans=(h,))
        if not group:
            continue
        cells = [
            Median(Select(group, method=m), panel.metric).Format() for m in methods
        ]
        for o in others:
            d = Difference(group, panel.metric, o, first)
            cells.append(d.Format(with_n=True))
        lines.append(f"| {h} | " + " | ".join(cells) + " |")
    return lines + [""]


def _Summary(study, rows) -> list[str]:
    methods = [m.name for m in study.methods]
    lines = [
        "| cell | method | runs | " + " | ".join(study.summary) + " |",
        "|---|---|---|" + "---|" * len(study.summary),
    ]
    for cell in study.cells:
        for method in methods:
            group = [
                r
                for r in Select(rows, method=method, humans=(cell.humans,))
                if r["scenario"] == cell.scenario
            ]
            if not group:
                continue
            stats = []
            for key in study.summary:
                if key in _BOOLEAN:
                    stats.append(_Rate(group, key))
                else:
                    values = [Value(r, key) for r in group]
                    values = [v for v in values if not math.isnan(v)]
                    stats.append(
                        f"{np.median(values):.3g} ({np.mean(values):.3g})"
                        if values
                        else "–"
                    )
            lines.append(
                f"| {cell.name} | {method} | {len(group)} | " + " | ".join(stats) + " |"
            )
    return lines + [""]


def WriteReport(
    study,
    rows,
    out_dir,
    plots,
    *,
    wall_time_s: float,
    ran: int,
    study_wall_time_s: float | None = None,
) -> Path:
    """Writes ``<study>_report.md``: per variant and people model, the
    plot, the panels' medians with 95 % CIs and the paired differences to
    the first method, a per-cell summary, and the "what holds" table of the
    study's findings."""
    ok = [r for r in rows if r.get("status") == "ok"]
    failed = [r for r in rows if r.get("status") != "ok"]
    busy = sum(float(r.get("wall_time_s") or 0.0) for r in rows)
    total = wall_time_s if study_wall_time_s is None else study_wall_time_s
    lines = [
        f"# Study `{study.name}`",
        "",
        study.description,
        "",
        f"- Runs in the CSV: {len(rows)} ({len(ok)} completed, {len(failed)} "
        f"failed to run), {busy / 60:.1f} min of run time in all.",
        f"- Study wall time: {total / 60:.1f} min over every invocation into "
        f"this directory; this invocation ran {ran} runs in "
        f"{wall_time_s / 60:.1f} min.",
        f"- Written {datetime.datetime.now().isoformat(timespec='seconds')}; "
        f"replay any run with `sm2ith replay {study.name}.csv ROW`.",
        "- Medians with percentile-bootstrap 95 % CIs [low, high]; "
        "differences are the mean over seeds of the paired difference (same "
        "cell, seed, variant and people), with a paired bootstrap 95 % CI "
        "and the number of pairs. Booleans count as 1/0; a run that did not "
        "reach its goal counts its time limit as navigation time and time to "
        "goal (a lower bound).",
        "",
    ]
    plot_by_tag = {Path(p).stem.removeprefix(f"{study.name}_"): p for p in plots}
    for variant, people in Axes(ok):
        group = Select(ok, variant=variant, people=people)
        lines += [f"## Variant `{variant}`, people `{people}`", ""]
        plot = plot_by_tag.get(_Tag(variant, people))
        if plot is not None:
            lines += [f"![{study.name}]({Path(plot).name})", ""]
        lines += ["### Panels", ""]
        for panel in study.panels:
            if Select(group, family=panel.family):
                lines += _PanelTable(study, group, panel)
        lines += [
            "### Per cell and method",
            "",
            "Booleans are counts over the runs; numbers are median (mean).",
            "",
        ]
        lines += _Summary(study, group)
    entries = FindingRows(study, ok)
    if entries:
        lines += ["## What holds", ""] + WhatHoldsTable(entries) + [""]
    if failed:
        lines += ["", "## Runs that failed to run", ""]
        lines += [f"- {r['run_id']}: {r.get('error', '')}" for r in failed]
    path = Path(out_dir) / f"{study.name}_report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
