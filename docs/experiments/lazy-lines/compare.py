"""SM²ITH's 5-person doorway runs with ``controller.lazy_line_margin``
against the same runs (run id for run id) of the shipped controller
without it: per robot, variant and people model, arrivals, runs with
contact (and with the robot closing in), the deepest contact, and the
paired differences of success, time to goal, the smallest gap and the
runs' step times with their bootstrap 95 % CIs.

    python docs/experiments/lazy-lines/compare.py NEW.csv BASE.csv...
"""

import sys
from collections import defaultdict

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

new = {r["run_id"]: r for r in ReadRows(sys.argv[1])}
base = {r["run_id"]: r for path in sys.argv[2:] for r in ReadRows(path)}
cells = defaultdict(list)
for run_id, row in sorted(new.items()):
    if run_id in base:
        cells[(row["robot"], row["variant"], row["people"])].append((row, base[run_id]))


def Values(pairs, key, index):
    return np.array([float(p[index][key]) for p in pairs])


for (robot, variant, people), pairs in sorted(cells.items()):
    print(f"{robot} {variant} {people}: {len(pairs)} runs (new / base)")
    for key in ("success", "collision", "robot_closing_contact"):
        a, b = Values(pairs, key, 0), Values(pairs, key, 1)
        print(f"  {key}: {int(a.sum())} / {int(b.sum())}", end="")
        if key == "success":
            d = PairedDifference(a, b)
            print(f"  (paired {d.value:+.3f} [{d.low:+.3f}, {d.high:+.3f}])", end="")
        print()
    gap_a, gap_b = Values(pairs, "min_human_gap", 0), Values(pairs, "min_human_gap", 1)
    print(
        f"  deepest contact mm: {min(0, gap_a.min()) * 1e3:.0f} / {min(0, gap_b.min()) * 1e3:.0f}"
    )
    for key in (
        "time_to_goal",
        "min_human_gap",
        "freezing_time",
        "step_time_median_ms",
        "step_time_p95_ms",
        "step_time_max_ms",
    ):
        a, b = Values(pairs, key, 0), Values(pairs, key, 1)
        d = PairedDifference(a, b)
        print(
            f"  {key}: mean {np.nanmean(a):.3f} / {np.nanmean(b):.3f}, paired "
            f"{d.value:+.3f} [{d.low:+.3f}, {d.high:+.3f}] (n={d.n})"
        )
    same = sum(
        abs(
            float(p[0]["time_to_goal"] or np.nan)
            - float(p[1]["time_to_goal"] or np.nan)
        )
        < 1e-9
        for p in pairs
    )
    print(f"  runs with the same time to goal: {same}")
