"""Runs in which the robot's own motion closed the gap during a contact
(``robot_closing_contact``), per method, in the Stretch 3's doorway at 30
seeds per count among ORCA people (docs/experiments/doorway-30-89b0a40),
and SM²ITH's paired differences against CVMM and React with bootstrap 95 %
confidence intervals (pooled over the counts, the same seeds).

    python docs/experiments/contact-kinds/closing30.py
"""

import csv
from pathlib import Path

import numpy as np
from scipy.stats import bootstrap

CSV = Path(__file__).parents[1] / "doorway-30-89b0a40" / "doorway.csv"

with open(CSV) as f:
    rows = [r for r in csv.DictReader(f) if r["people"] == "orca"]
closing = {
    (r["variant"], r["method"], r["humans"], r["seed"]): r["robot_closing_contact"]
    == "True"
    for r in rows
}
for variant in ("safe", "paper"):
    cells = sorted({(h, s) for (v, _, h, s) in closing if v == variant})
    counts = {
        m: sum(closing[(variant, m, h, s)] for h, s in cells)
        for m in ("SM2ITH", "CVMM", "React")
    }
    print(f"{variant}: runs with the robot closing in, of {len(cells)}: {counts}")
    for other in ("CVMM", "React"):
        diff = np.array(
            [
                float(closing[(variant, "SM2ITH", h, s)])
                - float(closing[(variant, other, h, s)])
                for h, s in cells
            ]
        )
        ci = bootstrap(
            (diff,), np.mean, n_resamples=10000, random_state=0, method="percentile"
        ).confidence_interval
        print(f"  SM²ITH − {other}: {diff.mean():+.3f} [{ci.low:+.3f}, {ci.high:+.3f}]")
