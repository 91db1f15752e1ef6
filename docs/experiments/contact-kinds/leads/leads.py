"""Which part of SM²ITH's prediction has its robot close in on ORCA people
more often than CVMM's, in the Stretch 3's doorway (safe, ORCA people, 30
seeds per count, 1/2/3/5 people: 120 runs per campaign): each campaign's
SM²ITH runs against the shipped SM²ITH and against CVMM on the same seeds,
pooled over the counts: runs that arrived, runs with contact, runs with
the robot closing in, with paired bootstrap 95 % CIs.

    python docs/experiments/contact-kinds/leads/leads.py

The shipped runs: docs/experiments/doorway-30-89b0a40 (1–3 people, and
CVMM) and docs/experiments/lazy-lines-f75c93c (SM²ITH with 5 people, whose
plans changed at f75c93c); each campaign below is one `sm2ith experiment
doorway` with one --scenario_text (README in this directory).
"""

from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
EXPERIMENTS = HERE.parents[1]
CAMPAIGNS = (
    "one-pass",
    "no-neighbors",
    "share0-no-neighbors",
    "no-overtaking",
    "near-cv",
    "guard-gap-0.5",
    "guard-close",
)
METRICS = (
    ("success", "arrived"),
    ("collision", "with contact"),
    ("robot_closing_contact", "robot closing in"),
)


def Key(row):
    return (row["humans"], row["seed"])


def Runs(path, method):
    return {
        Key(r): r
        for r in ReadRows(path)
        if r["method"] == method
        and r["variant"] == "safe"
        and r["people"] == "orca"
        and r["robot"] == "stretch3"
    }


shipped = Runs(EXPERIMENTS / "doorway-30-89b0a40" / "doorway.csv", "SM2ITH")
shipped.update(
    Runs(EXPERIMENTS / "lazy-lines-f75c93c" / "doorway_stretch3.csv", "SM2ITH")
)
cvmm = Runs(EXPERIMENTS / "doorway-30-89b0a40" / "doorway.csv", "CVMM")


def Line(name, runs, against=None):
    keys = sorted(runs)
    parts = []
    for key, label in METRICS:
        a = np.array([float(runs[k][key]) for k in keys])
        text = f"{label} {int(a.sum())}"
        for other, tag in against or ():
            b = np.array([float(other[k][key]) for k in keys])
            d = PairedDifference(a, b)
            text += f" ({tag} {d.value:+.3f} [{d.low:+.3f}, {d.high:+.3f}])"
        parts.append(text)
    print(f"{name} ({len(keys)} runs): " + "; ".join(parts))


Line("SM²ITH shipped", shipped, [(cvmm, "− CVMM")])
Line("CVMM", cvmm)
for name in CAMPAIGNS:
    runs = Runs(HERE / name / "doorway.csv", "SM2ITH")
    Line(name, runs, [(shipped, "− shipped"), (cvmm, "− CVMM")])

# The overtaking rule's other side: SM²ITH without it among people who do
# not follow its model (no-overtaking-others), and with overtakers within
# the guard's gap held (guard-close, instructed people), against the
# shipped SM²ITH and CVMM on the same seeds.
print()
for people in ("instructed", "social_force"):

    def Others(path, method, people=people):
        return {
            Key(r): r
            for r in ReadRows(path)
            if r["method"] == method
            and r["variant"] == "safe"
            and r["people"] == people
            and r["robot"] == "stretch3"
        }

    base = Others(EXPERIMENTS / "doorway-30-89b0a40" / "doorway.csv", "SM2ITH")
    base.update(
        Others(EXPERIMENTS / "lazy-lines-f75c93c" / "doorway_stretch3.csv", "SM2ITH")
    )
    others = Others(EXPERIMENTS / "doorway-30-89b0a40" / "doorway.csv", "CVMM")
    print(f"{people}:")
    Line("  SM²ITH shipped", base, [(others, "− CVMM")])
    Line("  CVMM", others)
    Line(
        "  no-overtaking",
        Others(HERE / "no-overtaking-others" / "doorway.csv", "SM2ITH"),
        [(base, "− shipped"), (others, "− CVMM")],
    )
    if people == "instructed":
        Line(
            "  guard-close",
            Others(HERE / "guard-close" / "doorway.csv", "SM2ITH"),
            [(base, "− shipped"), (others, "− CVMM")],
        )
