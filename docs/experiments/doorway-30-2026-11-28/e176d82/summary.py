"""The Stretch 3 doorway at 30 seeds per count on the controller of e176d82,
every method on the same seeds: arrivals by people count (1/2/3/5), SM²ITH's
paired difference in arrivals against CVMM and React (pooled, [95 % CI]),
and runs with contact, per people model and variant.

    D=docs/experiments/doorway-30-2026-11-28/e176d82
    sm2ith experiment doorway --runs 30 --variant paper --people orca \\
        --only doorway_stretch3 --jobs 2 --out $D/orca-paper
    sm2ith experiment doorway --runs 30 --variant safe --people social_force \\
        --only doorway_stretch3 --jobs 2 --out $D/social_force-safe
    (the same with --variant paper and --out $D/social_force-paper)
    python docs/experiments/doorway-30-2026-11-28/e176d82/summary.py

The other cells come from runs that are the same as e176d82's: `safe` with
instructed and ORCA people, SM²ITH's with ``guard_gap: 0.2`` (``gap20``,
``orca30-gap20``) and the baselines' from before it (the guard gap does not
touch them: ``../doorway.csv``, ``orca30-default``); `paper` with
instructed people from 469abf3 (``default-469abf3`` and ``../doorway.csv``;
`paper` has no guard), with its one run that had a failed solve taken
from the final re-run on e176d82 (``../../final-e176d82``), which re-ran
it. Output: summary.txt.
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
RUNS = HERE.parent
OPT = RUNS / "overtaking"
# (people, variant): {method: directory}
CELLS = {
    ("instructed", "safe"): {"SM2ITH": OPT / "gap20", "CVMM": RUNS, "React": RUNS},
    ("instructed", "paper"): {
        "SM2ITH": OPT / "default-469abf3",
        "CVMM": RUNS,
        "React": RUNS,
    },
    ("orca", "safe"): {
        "SM2ITH": OPT / "orca30-gap20",
        "CVMM": OPT / "orca30-default",
        "React": OPT / "orca30-default",
    },
    ("orca", "paper"): dict.fromkeys(("SM2ITH", "CVMM", "React"), HERE / "orca-paper"),
    ("social_force", "safe"): dict.fromkeys(
        ("SM2ITH", "CVMM", "React"), HERE / "social_force-safe"
    ),
    ("social_force", "paper"): dict.fromkeys(
        ("SM2ITH", "CVMM", "React"), HERE / "social_force-paper"
    ),
}


FINAL = RUNS.parent / "final-e176d82" / "doorway.csv"


def Rows(directory, people, variant, method):
    rows = ReadRows(directory / "doorway.csv")
    if directory.name == "default-469abf3":
        # Its runs with a failed solve are what e176d82 changes.
        final = {r["run_id"]: r for r in ReadRows(FINAL)}
        rows = [final[r["run_id"]] if r["solver_failures"] > 0 else r for r in rows]
    return {
        (r["humans"], r["seed"]): r
        for r in rows
        if (r["robot"], r["people"], r["variant"], r["method"])
        == ("stretch3", people, variant, method)
    }


def main():
    lines = []
    for (people, variant), sources in CELLS.items():
        if not all((d / "doorway.csv").exists() for d in sources.values()):
            continue
        rows = {m: Rows(d, people, variant, m) for m, d in sources.items()}
        keys = sorted(set.intersection(*(set(r) for r in rows.values())))
        ok = {
            m: [float(r[k]["success"] is True) for k in keys] for m, r in rows.items()
        }
        text = f"{people:12s} {variant:5s} ({len(keys)} runs per method):"
        for m, r in rows.items():
            counts = "/".join(
                str(sum(r[k]["success"] is True for k in keys if k[0] == h))
                for h in (1, 2, 3, 5)
            )
            contact = sum(r[k]["collision"] is True for k in keys)
            text += f" {m} {int(sum(ok[m]))} ({counts}), contact {contact};"
        for m in ("CVMM", "React"):
            e = PairedDifference(ok["SM2ITH"], ok[m])
            text += f" − {m} {e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"
        lines.append(text)
    text = "\n".join(lines)
    print(text)
    (HERE / "summary.txt").write_text(text + "\n")


if __name__ == "__main__":
    main()
