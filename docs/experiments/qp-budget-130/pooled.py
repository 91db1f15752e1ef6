"""SM²ITH's 5-person doorway runs with ``controller.qp_iteration_budget``
against the same runs without it (run id for run id), pooled per robot
and variant and over both variants: arrivals, runs with contact, and the
paired mean differences of success, freezing time and the runs' longest
step with bootstrap 95 % CIs.

    python docs/experiments/qp-budget-130/pooled.py NEW.csv BASE.csv...
"""

import sys
from collections import defaultdict

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

new = {r["run_id"]: r for r in ReadRows(sys.argv[1])}
base = {r["run_id"]: r for path in sys.argv[2:] for r in ReadRows(path)}
groups = defaultdict(list)
for run_id, row in sorted(new.items()):
    if run_id in base:
        for variant in (row["variant"], "both"):
            groups[(row["robot"], variant)].append((row, base[run_id]))

for (robot, variant), pairs in sorted(groups.items()):
    print(f"{robot} {variant}: {len(pairs)} runs (new / base)")
    for key in (
        "success",
        "collision",
        "robot_closing_contact",
        "freezing_time",
        "time_to_goal",
        "step_time_max_ms",
    ):
        a = np.array([float(p[0][key]) for p in pairs])
        b = np.array([float(p[1][key]) for p in pairs])
        d = PairedDifference(a, b)
        totals = (
            f"{int(np.nansum(a))} / {int(np.nansum(b))}"
            if key in ("success", "collision", "robot_closing_contact")
            else f"mean {np.nanmean(a):.2f} / {np.nanmean(b):.2f}"
        )
        print(
            f"  {key}: {totals}, paired {d.value:+.3f} [{d.low:+.3f}, {d.high:+.3f}]"
            f" (n={d.n})"
        )
