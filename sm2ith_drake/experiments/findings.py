"""Paired comparisons of a study's rows and the "what holds" table of the
paper's findings (a)–(d) (issue 12).

Rows pair on (cell, seed) within one variant and people model: the two
methods met the same people. A run that did not reach its goal counts with
its time limit as its navigation time and time to goal (a lower bound, so a
method that times out is not compared on its successes alone); pairs where
either value is still missing are dropped, so each estimate states its
number of pairs.
"""

from __future__ import annotations

import math
from pathlib import Path

from sm2ith_drake.experiments.statistics import (
    Estimate,
    MedianCI,
    PairedDifference,
    Verdict,
)

# Times that are NaN when the goal was not reached: then the time limit.
_CENSORED = ("navigation_time", "time_to_goal")

# A metric derived from two columns: the run succeeded and touched nobody
# (a doorway crossed by pushing into people is not a success for a
# controller meant to be safe among them).
CONTACT_FREE_SUCCESS = "contact_free_success"


def Value(row: dict, metric: str) -> float:
    """A row's metric as a float (booleans 1/0, missing NaN; a time to a
    goal never reached: the run's simulated time, its time limit)."""
    if metric == CONTACT_FREE_SUCCESS:
        success, contact = row.get("success"), row.get("collision")
        if not isinstance(success, bool) or not isinstance(contact, bool):
            return math.nan
        return float(success and not contact)
    v = row.get(metric, math.nan)
    if metric in _CENSORED and _Nan(v) and row.get("success") is False:
        v = row.get("simulated_time", math.nan)
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, str):
        try:
            return float(v)
        except ValueError:
            return math.nan
    return float(v)


def _Nan(v) -> bool:
    return v is None or v == "" or (isinstance(v, float) and math.isnan(v))


def Axes(rows) -> list[tuple[str, str]]:
    """The (variant, people) combinations present in ``rows``, sorted."""
    return sorted({(r.get("variant", ""), r.get("people", "")) for r in rows})


def Select(rows, *, family=None, humans=(), variant=None, people=None, method=None):
    """The completed rows matching every given filter."""
    out = []
    for r in rows:
        if r.get("status") != "ok":
            continue
        if family is not None and r["family"] != family:
            continue
        if humans and r["humans"] not in humans:
            continue
        if variant is not None and r.get("variant") != variant:
            continue
        if people is not None and r.get("people") != people:
            continue
        if method is not None and r["method"] != method:
            continue
        out.append(r)
    return out


def _CellKey(r) -> tuple:
    return (r["scenario"], r["humans"], r["seed"])


def Paired(rows, metric: str, method: str, other: str) -> tuple[list, list]:
    """The values of ``method`` and ``other`` on the (cell, seed) pairs both
    completed, in the same order."""
    a = {_CellKey(r): Value(r, metric) for r in rows if r["method"] == method}
    b = {_CellKey(r): Value(r, metric) for r in rows if r["method"] == other}
    keys = sorted(set(a) & set(b))
    return [a[k] for k in keys], [b[k] for k in keys]


def Difference(rows, metric: str, method: str, other: str) -> Estimate:
    """``method`` − ``other`` on ``metric``: the mean paired difference with
    its 95 % CI (statistics.PairedDifference)."""
    a, b = Paired(rows, metric, method, other)
    return PairedDifference(a, b)


def Median(rows, metric: str) -> Estimate:
    return MedianCI([Value(r, metric) for r in rows])


def FindingRows(study, rows) -> list[dict]:
    """One entry per finding of the study and (variant, people) in the
    rows: the claim, the paired differences and the verdict."""
    out = []
    robots = {c.family: c.robot for c in study.cells}
    for variant, people in Axes(rows):
        for f in study.findings:
            group = Select(
                rows, family=f.family, humans=f.humans, variant=variant, people=people
            )
            diffs = [Difference(group, f.metric, f.method, o) for o in f.than]
            out.append(
                {
                    "key": f.key,
                    "claim": f.claim,
                    "robot": robots.get(f.family, f.family),
                    "variant": variant,
                    "people": people,
                    "metric": f.metric,
                    "humans": f.humans,
                    "comparisons": [
                        (f"{f.method} − {o}", d)
                        for o, d in zip(f.than, diffs, strict=True)
                    ],
                    "verdict": Verdict(diffs, lower_is_better=f.lower_is_better),
                }
            )
    return out


def WhatHoldsTable(entries) -> list[str]:
    """Markdown lines: one row per finding, robot, people model and
    variant."""
    if not entries:
        return []
    lines = [
        "| finding | claim | robot | people | variant | paired difference "
        "(mean [95 % CI], pairs n) | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for e in entries:
        diffs = "; ".join(
            f"{name}: {d.Format(with_n=True)}" for name, d in e["comparisons"]
        )
        lines.append(
            f"| {e['key']} | {e['claim']} | {e['robot']} | {e['people']} | "
            f"{e['variant']} | {diffs} | **{e['verdict']}** |"
        )
    return lines


def WriteFindings(studies, rows_by_study: dict, out_dir) -> Path:
    """Writes ``<out_dir>/findings.md``: the "what holds" table over every
    study with rows."""
    lines = [
        "# What holds of the paper's findings",
        "",
        "Paired on seed within each cell, variant and people model; a finding "
        "holds when every paired difference's 95 % bootstrap CI lies on the "
        "claimed side of 0, does not hold when one lies on the other side, "
        "and is not distinguishable at this sample size otherwise.",
        "",
    ]
    for name, study in studies.items():
        rows = rows_by_study.get(name)
        if not rows or not study.findings:
            continue
        lines += [f"## {name}", ""] + WhatHoldsTable(FindingRows(study, rows)) + [""]
    path = Path(out_dir) / "findings.md"
    path.write_text("\n".join(lines) + "\n")
    return path
