"""safety.no_closer_gap in the Stretch 3's doorway (safe, ORCA people, 30
seeds per count, 1/2/3/5 people): each campaign's runs of a method against
the same method's shipped runs on the same seeds, pooled over the counts:
arrivals, runs with contact, runs with the robot closing in, the deepest
contact, freezing time; paired bootstrap 95 % CIs.

    python docs/experiments/no-closer/compare.py CAMPAIGN_DIR [METHOD ...]

How far the robot closed in on people it touched (``robot_closing_distance``,
mm) is read from CAMPAIGN_DIR/closing.csv and this directory's
closing_shipped.csv where the campaign CSVs do not carry it (closing.py
writes them; a run without robot_closing_contact closed in by 0).

The shipped runs: docs/experiments/doorway-30-89b0a40 (the Stretch 3, 1–3
people, every method; 5 people CVMM and React), final-89b0a40 (the same
for the Ridgeback–UR10, 10 seeds) and qp-budget-130/budget-120 (SM²ITH with
5 people, whose plans changed with the budget).
"""

import csv
import sys
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

EXPERIMENTS = Path(__file__).parents[1]
METRICS = (
    ("success", "arrived"),
    ("collision", "with contact"),
    ("robot_closing_contact", "robot closing in"),
)


def Runs(path, method, people="orca", robot="stretch3"):
    return {
        (r["humans"], r["seed"]): r
        for r in ReadRows(path)
        if r["method"] == method
        and r["variant"] == "safe"
        and r["people"] == people
        and r["robot"] == robot
    }


def Shipped(method, people="orca", robot="stretch3"):
    """The shipped controller's runs: the Stretch 3's 30-seed set, the
    Ridgeback–UR10's 10 seeds (final-89b0a40), SM²ITH's 5-person runs from
    the budget's re-run."""
    base = "doorway-30-89b0a40" if robot == "stretch3" else "final-89b0a40"
    runs = Runs(EXPERIMENTS / base / "doorway.csv", method, people, robot)
    if method == "SM2ITH":
        runs = {k: r for k, r in runs.items() if str(r["humans"]) != "5"}
        runs.update(
            Runs(
                EXPERIMENTS / "qp-budget-130" / "budget-120" / f"doorway_{robot}.csv",
                method,
                people,
                robot,
            )
        )
    return runs


def ClosingMm(path):
    """run_id → mm from a closing.py output (empty if it is missing)."""
    if not Path(path).exists():
        return {}
    with open(path, newline="") as f:
        return {r["run_id"]: float(r["closing_mm"]) for r in csv.DictReader(f)}


def AddClosing(runs, closing):
    """Each run's ``closing_mm``: its own column, or ``closing``'s figure,
    or 0 without robot_closing_contact; NaN where none is known."""
    for r in runs.values():
        own = r.get("robot_closing_distance")
        if isinstance(own, float) and own == own:
            r["closing_mm"] = 1e3 * own
        elif r["robot_closing_contact"] is not True:
            r["closing_mm"] = 0.0
        else:
            r["closing_mm"] = closing.get(r["run_id"], float("nan"))


def Compare(new, base, name):
    keys = sorted(set(new) & set(base))
    print(f"{name}: {len(keys)} paired runs (new / shipped)")
    for key, label in METRICS:
        a = np.array([float(new[k][key]) for k in keys])
        b = np.array([float(base[k][key]) for k in keys])
        d = PairedDifference(a, b)
        print(
            f"  {label}: {int(a.sum())} / {int(b.sum())}, "
            f"{d.value:+.3f} [{d.low:+.3f}, {d.high:+.3f}]"
        )
    a = np.array([new[k]["closing_mm"] for k in keys])
    b = np.array([base[k]["closing_mm"] for k in keys])
    if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
        d = PairedDifference(a, b)
        print(
            f"  robot closing in, mm in all runs: {a.sum():.0f} / {b.sum():.0f}, "
            f"per run {d.value:+.2f} [{d.low:+.2f}, {d.high:+.2f}]; "
            f"runs over 5 mm {int((a > 5).sum())} / {int((b > 5).sum())}"
        )
    for key, label, scale in (
        ("min_human_gap", "deepest contact mm", -1000.0),
        ("freezing_time", "freezing time s", 1.0),
        ("time_to_goal", "time to goal s (arrived in both)", 1.0),
    ):
        both = [
            k
            for k in keys
            if key != "time_to_goal"
            or (float(new[k]["success"]) and float(base[k]["success"]))
        ]
        a = np.array([float(new[k][key]) for k in both])
        b = np.array([float(base[k][key]) for k in both])
        if key == "min_human_gap":
            print(f"  {label}: {scale * a.min():.0f} / {scale * b.min():.0f}")
            continue
        d = PairedDifference(a, b)
        print(
            f"  {label}: mean {a.mean():.2f} / {b.mean():.2f}, "
            f"{d.value:+.2f} [{d.low:+.2f}, {d.high:+.2f}] (n={len(both)})"
        )
    counts = sorted({str(k[0]) for k in keys}, key=int)
    for key, label in METRICS[1:]:
        per = [
            f"{sum(float(new[k][key]) for k in keys if str(k[0]) == c):.0f}/"
            f"{sum(float(base[k][key]) for k in keys if str(k[0]) == c):.0f}"
            for c in counts
        ]
        print(f"  {label} by count {'/'.join(counts)}: " + ", ".join(per))


if __name__ == "__main__":
    campaign = Path(sys.argv[1])
    methods = sys.argv[2:] or ["SM2ITH"]
    new_closing = ClosingMm(campaign / "closing.csv")
    base_closing = ClosingMm(Path(__file__).parent / "closing_shipped.csv")
    for robot in ("stretch3", "ridgeback_ur10"):
        for people in ("orca", "instructed", "social_force"):
            for method in methods:
                new = Runs(campaign / "doorway.csv", method, people, robot)
                if new:
                    base = Shipped(method, people, robot)
                    AddClosing(new, new_closing)
                    AddClosing(base, base_closing)
                    Compare(new, base, f"{robot}, {method}, {people}")
