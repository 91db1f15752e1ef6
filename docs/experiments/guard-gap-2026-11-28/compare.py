"""The Stretch 3 doorway in `safe`, 30 seeds per count (1/2/3/5 people):
SM²ITH with ``safety.guard_gap`` (people measured within that gap of the
robot's nearest body held in the guard) against the default of 469abf3 on
the same (count, seed), and against CVMM's and React's default runs:
arrivals, runs with contact, runs with the robot closing in, and the
deepest contact; paired differences with bootstrap 95 % CIs.

    sm2ith experiment doorway --runs 30 --variant safe --people instructed \\
        --only doorway_stretch3 --methods SM2ITH --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/overtaking/gap20 \\
        --scenario_text '{safety: {guard_gap: 0.2}}'
    (the same with --people orca and --out .../orca30-gap20)
    python docs/experiments/guard-gap-2026-11-28/compare.py [OPTION_DIR ...]

OPTION_DIR: directories under doorway-30-2026-11-28/overtaking/ (default:
gap20 and orca30-gap20); a name starting with ``orca30`` is read as ORCA
people. Output: compare.txt beside this script (for the default dirs).
"""

import sys
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
RUNS = HERE.parent / "doorway-30-2026-11-28"
OPTIONS = RUNS / "overtaking"
# Per people model: the 469abf3 default's SM²ITH runs, and the baselines'.
DEFAULTS = {
    "instructed": (OPTIONS / "keep90", RUNS),
    "orca": (OPTIONS / "orca30-keep90", OPTIONS / "orca30-default"),
}


def Rows(directory, people, method):
    """(count, seed) → row of ``method``'s `safe` Stretch 3 runs."""
    return {
        (r["humans"], r["seed"]): r
        for r in ReadRows(directory / "doorway.csv")
        if (r["robot"], r["people"], r["variant"], r["method"])
        == ("stretch3", people, "safe", method)
    }


def Flags(rows, keys, field):
    return [float(rows[k][field] is True) for k in keys]


def CI(a, b):
    e = PairedDifference(a, b)
    return f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"


def Deepest(rows, keys):
    gaps = [rows[k]["min_human_gap"] for k in keys if rows[k]["collision"] is True]
    return f"{-1000 * min(gaps):.0f} mm" if gaps else "-"


def Compare(name):
    people = "orca" if name.startswith("orca30") else "instructed"
    option = Rows(OPTIONS / name, people, "SM2ITH")
    default_dir, baseline_dir = DEFAULTS[people]
    others = {"SM2ITH (469abf3)": Rows(default_dir, people, "SM2ITH")}
    for m in ("CVMM", "React"):
        others[m] = Rows(baseline_dir, people, m)
    keys = sorted(option)
    lines = [f"{name} ({people} people, {len(keys)} runs):"]
    counts = "/".join(
        str(int(sum(Flags(option, [k for k in keys if k[0] == h], "success"))))
        for h in (1, 2, 3, 5)
    )
    fields = ("success", "collision", "robot_closing_contact")
    ours = {f: Flags(option, keys, f) for f in fields}
    lines.append(
        f"  option: arrivals {int(sum(ours['success']))} ({counts}), contact "
        f"{int(sum(ours['collision']))}, closing "
        f"{int(sum(ours['robot_closing_contact']))}, deepest {Deepest(option, keys)}"
    )
    for label, rows in others.items():
        text = f"  − {label}:"
        for f in fields:
            theirs = Flags(rows, keys, f)
            text += f" {f} {int(sum(theirs))} ({CI(ours[f], theirs)})"
        lines.append(text + f", deepest {Deepest(rows, keys)}")
    times = [
        (option[k]["time_to_goal"], others["SM2ITH (469abf3)"][k]["time_to_goal"])
        for k in keys
        if option[k]["success"] is True and others["SM2ITH (469abf3)"][k]["success"]
    ]
    if times:
        a, b = np.array(times, dtype=float).T
        lines.append(
            f"  time to goal where both arrive ({len(times)} runs): median "
            f"{np.median(a):.1f} s against {np.median(b):.1f} s, "
            f"difference {CI(list(a), list(b))} s"
        )
    return lines


def main(names):
    text = "\n".join(line for n in names for line in Compare(n))
    print(text)
    if names == ["gap20", "orca30-gap20"]:
        (HERE / "compare.txt").write_text(text + "\n")


if __name__ == "__main__":
    main(sys.argv[1:] or ["gap20", "orca30-gap20"])
