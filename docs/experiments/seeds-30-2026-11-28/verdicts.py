"""The paper's findings (a)-(d) at 10 and at 30 seeds, side by side, from
this directory's CSVs (seeds 0-9 are the final re-run's runs, seeds 10-29
were run on the same controller), and the runs with contact per study,
method, people model and variant.

python docs/experiments/seeds-30-2026-11-28/verdicts.py [STUDY ...]
"""

import sys
from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.findings import Difference, FindingRows, Select
from sm2ith_drake.experiments.statistics import NOT_DISTINGUISHABLE
from sm2ith_drake.experiments.studies import STUDIES

HERE = Path(__file__).resolve().parent


def _Text(entry) -> str:
    diffs = "; ".join(
        f"{d.value:+.3g} [{d.low:+.3g}, {d.high:+.3g}] n={d.n}"
        for _, d in entry["comparisons"]
    )
    verdict = entry["verdict"]
    if verdict == NOT_DISTINGUISHABLE:
        verdict = "n.d."
    return f"{verdict} ({diffs})"


def Verdicts(name, rows):
    study = STUDIES[name]
    first = FindingRows(study, [r for r in rows if r["seed"] < 10])
    every = FindingRows(study, rows)
    print(f"## {name}\n")
    print("| finding | robot | people | variant | 10 seeds | 30 seeds |")
    print("|---|---|---|---|---|---|")
    changed = 0
    for a, b in zip(first, every, strict=True):
        assert (a["claim"], a["variant"], a["people"]) == (
            b["claim"],
            b["variant"],
            b["people"],
        )
        moved = a["verdict"] != b["verdict"]
        changed += moved
        mark = " **(changed)**" if moved else ""
        print(
            f"| {a['key']} {a['claim']} | {a['robot']} | {a['people']} | "
            f"{a['variant']} | {_Text(a)} | {_Text(b)}{mark} |"
        )
    print(f"\n{changed} of {len(first)} verdicts changed.\n")


def HeadOn(rows):
    """The head-on runs' arrivals and time to goal, SM²ITH − CVMM, paired,
    at 10 and at 30 seeds (the paper's (d) names time to goal beside the
    two claims)."""
    print("Head-on, SM²ITH − CVMM (mean paired difference [95 % CI]):\n")
    print("| metric | people | variant | 10 seeds | 30 seeds |")
    print("|---|---|---|---|---|")
    for metric in ("success", "time_to_goal"):
        for people in ("orca", "instructed", "social_force"):
            for variant in ("paper", "safe"):
                group = Select(rows, family="headon", variant=variant, people=people)
                cells = []
                for seeds in (10, 30):
                    g = [r for r in group if r["seed"] < seeds]
                    d = Difference(g, metric, "SM2ITH", "CVMM")
                    cells.append(f"{d.value:+.3g} [{d.low:+.3g}, {d.high:+.3g}]")
                cells = " | ".join(cells)
                print(f"| {metric} | {people} | {variant} | {cells} |")
    print()


def Contacts(name, rows):
    print(f"Runs with contact ({name}; in brackets the robot closing in):\n")
    methods = sorted({r["method"] for r in rows})
    print("| people | variant | " + " | ".join(methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    for people in sorted({r["people"] for r in rows}):
        for variant in ("paper", "safe"):
            cells = []
            for m in methods:
                runs = [
                    r
                    for r in rows
                    if r["method"] == m
                    and r["people"] == people
                    and r["variant"] == variant
                ]
                hit = sum(r["collision"] is True for r in runs)
                closing = sum(r["robot_closing_contact"] is True for r in runs)
                cells.append(f"{hit} ({closing}) of {len(runs)}")
            print(f"| {people} | {variant} | " + " | ".join(cells) + " |")
    print()


def main(names):
    for name in names:
        path = HERE / f"{name}.csv"
        if not path.exists():
            continue
        rows = [r for r in ReadRows(path) if r.get("status") == "ok"]
        Verdicts(name, rows)
        if name == "adversarial":
            HeadOn(rows)
        Contacts(name, rows)


if __name__ == "__main__":
    main(sys.argv[1:] or ["adversarial", "pick_and_place", "banner_cup"])
