"""Arrivals, runs with contact, runs with the robot closing in and the
deepest contact per cell: a campaign CSV (first argument) against the same
runs of another (second; default docs/experiments/final-89b0a40/doorway.csv).

    python docs/experiments/contact-kinds/compare.py NEW.csv [BASE.csv]
"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

BASE = Path(__file__).parents[1] / "final-89b0a40" / "doorway.csv"


def Rows(path):
    with open(path) as f:
        return {r["run_id"]: r for r in csv.DictReader(f)}


new = Rows(sys.argv[1])
base = Rows(sys.argv[2] if len(sys.argv) > 2 else BASE)
cells = defaultdict(lambda: [0] * 8)
for run_id, row in new.items():
    old, s = base[run_id], cells[(row["robot"], row["humans"], row["method"])]
    for i, r in enumerate((row, old)):
        s[i] += r["success"] == "True"
        s[2 + i] += r["collision"] == "True"
        s[4 + i] += r["robot_closing_contact"] == "True"
        s[6 + i] = min(s[6 + i], float(r["min_human_gap"]))
total = [0] * 6
for key, s in sorted(cells.items()):
    print(
        key,
        f"arrivals {s[0]} vs {s[1]}  contact {s[2]} vs {s[3]}  closing {s[4]} vs "
        f"{s[5]}  deepest {s[6] * 1e3:.0f} vs {s[7] * 1e3:.0f} mm",
    )
    total = [t + v for t, v in zip(total, s[:6], strict=True)]
print(
    f"total arrivals {total[0]} vs {total[1]}  contact {total[2]} vs {total[3]}  "
    f"closing {total[4]} vs {total[5]}"
)
