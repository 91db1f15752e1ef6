"""The Stretch 3 doorway among ORCA people, `safe`, 30 seeds per count,
every method, with the simulated people seeing the robot's nearest body
move at its own velocity (``body_velocity.patch``) against the same runs
with the shipped simulator, where it moves with the base (SM²ITH on
e176d82: ``orca30-gap20``; CVMM and React: ``orca30-default``): arrivals,
runs with contact, runs with the robot closing in, per count and pooled,
with the paired difference [95 % CI].

    git apply docs/experiments/body-velocity-2026-11-28/body_velocity.patch
    sm2ith experiment doorway --runs 30 --variant safe --people orca \\
        --only doorway_stretch3 --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/overtaking/orca30-bodyv
    git apply -R docs/experiments/body-velocity-2026-11-28/body_velocity.patch
    python docs/experiments/body-velocity-2026-11-28/compare.py

Output: compare.txt beside this script.
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
RUNS = HERE.parent / "doorway-30-2026-11-28" / "overtaking"
OLD = {"SM2ITH": "orca30-gap20", "CVMM": "orca30-default", "React": "orca30-default"}
FIELDS = ("success", "collision", "robot_closing_contact")


def Rows(name, method):
    return {
        (r["humans"], r["seed"]): r
        for r in ReadRows(RUNS / name / "doorway.csv")
        if (r["method"], r["robot"], r["variant"]) == (method, "stretch3", "safe")
    }


def main():
    lines = []
    for method, old_name in OLD.items():
        new, old = Rows("orca30-bodyv", method), Rows(old_name, method)
        keys = sorted(k for k in new if k in old)
        for counts in ((1,), (2,), (3,), (5,), (1, 2, 3, 5)):
            ks = [k for k in keys if k[0] in counts]
            label = "pooled" if len(counts) > 1 else f"{counts[0]} people"
            text = f"{method:6s} {label:9s} ({len(ks)} runs):"
            for f in FIELDS:
                a = [float(new[k][f] is True) for k in ks]
                b = [float(old[k][f] is True) for k in ks]
                text += f" {f} {int(sum(a))} vs {int(sum(b))}"
                if len(counts) > 1:
                    e = PairedDifference(a, b)
                    text += f" ({e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}])"
            lines.append(text)
    text = "\n".join(lines)
    print(text)
    (HERE / "compare.txt").write_text(text + "\n")


if __name__ == "__main__":
    main()
