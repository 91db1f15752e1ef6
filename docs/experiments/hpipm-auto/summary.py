"""The head-on study with HPIPM for the stage QPs (controller.qp_solver:
auto) against the same study with PIQP (the default), SM²ITH, paired by
variant, people model and seed (README, Benchmark).

    python summary.py
"""

import csv
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
BASE = HERE.parent / "proximal-6b4b50a" / "adversarial_default.csv"
AUTO = HERE / "adversarial_auto.csv"


def Load(path):
    with open(path) as f:
        return {
            (r["variant"], r["people"], int(r["seed"])): r for r in csv.DictReader(f)
        }


def Ci(d):
    """Mean of the paired differences d with its 95 % bootstrap CI (the
    package's own PairedDifference, as the study reports use)."""
    d = np.asarray(d, dtype=float)
    if not len(d):
        return "n/a"
    e = PairedDifference(d, np.zeros_like(d))
    return f"{e.value:+.3f} [{e.low:+.3f}, {e.high:+.3f}]"


base, auto = Load(BASE), Load(AUTO)
keys = sorted(set(base) & set(auto))
print(f"paired runs: {len(keys)}")
for column in ("success", "collision", "robot_closing_contact", "wall_collision"):
    b = np.array([base[k][column] == "True" for k in keys], float)
    a = np.array([auto[k][column] == "True" for k in keys], float)
    print(f"{column}: piqp {int(b.sum())}, auto {int(a.sum())}, diff {Ci(a - b)}")
for column in ("progress_share", "base_retreat", "time_to_goal", "min_human_gap"):
    pairs = [(float(base[k][column]), float(auto[k][column])) for k in keys]
    pairs = np.array([p for p in pairs if np.all(np.isfinite(p))])
    print(
        f"{column} (n={len(pairs)}): median piqp {np.median(pairs[:, 0]):.3f}, "
        f"auto {np.median(pairs[:, 1]):.3f}, mean diff {Ci(pairs[:, 1] - pairs[:, 0])}"
    )
same = sum(base[k]["time_to_goal"] == auto[k]["time_to_goal"] for k in keys)
print(f"runs with the same time to goal to the digit: {same} of {len(keys)}")

# The banner/cup study (SM2ITH, both variants, ORCA and instructed people,
# seeds 0-9) with auto, against the default's rows of the c48edcd re-run
# (reproduced run for run by the PIQP default at ed6ca6a).
BANNER_BASE = HERE.parent / "rerun-c48edcd" / "banner_cup.csv"
BANNER_AUTO = HERE / "banner_cup_auto.csv"


def LoadBanner(path):
    with open(path) as f:
        return {
            (r["scenario"], r["variant"], r["people"], int(r["seed"])): r
            for r in csv.DictReader(f)
            if r["method"] == "SM2ITH"
        }


base, auto = LoadBanner(BANNER_BASE), LoadBanner(BANNER_AUTO)
print(f"banner/cup paired runs: {len(set(base) & set(auto))}")
for people in ("orca", "instructed", None):
    keys = sorted(k for k in set(base) & set(auto) if people in (None, k[2]))
    for column in ("success", "collision", "robot_closing_contact"):
        b = np.array([base[k][column] == "True" for k in keys], float)
        a = np.array([auto[k][column] == "True" for k in keys], float)
        counts = f"piqp {int(b.sum())}, auto {int(a.sum())}"
        print(f"  {people or 'pooled'} {column}: {counts}, diff {Ci(a - b)}")
for column in ("time_to_goal", "ee_error_mean", "min_human_gap"):
    pairs = np.array([(float(base[k][column]), float(auto[k][column])) for k in keys])
    pairs = pairs[np.all(np.isfinite(pairs), axis=1)]
    print(f"  {column} (n={len(pairs)}): mean diff {Ci(pairs[:, 1] - pairs[:, 0])}")
