"""The Stretch 3 doorway with instructed people, 30 seeds per person count,
with qp_solver auto: SM²ITH against CVMM and React, paired on (count,
seed), pooled and per count; beside it the same with piqp (the final
re-run, ``../doorway-30-final``, commit bfe42b6).

The auto runs are ``../qp-solver-auto/doorway/doorway.csv`` (68c389d, whose
plans with auto are those of the default since; CVMM and React ran in
``safe`` only: their ``paper`` and ``safe`` variants are one controller,
so the ``paper`` comparison pairs SM²ITH's ``paper`` runs with their
``safe`` runs, as the final re-run checked run for run).

    python docs/experiments/auto-rerun/doorway30.py
"""

from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
SOURCES = {
    "auto": HERE.parent / "qp-solver-auto" / "doorway" / "doorway.csv",
    "piqp (bfe42b6)": HERE.parent / "doorway-30-final" / "doorway.csv",
}
COUNTS = (1, 2, 3, 5)


def Success(rows, method, variant):
    """(count, seed) → 1.0 / 0.0 for the Stretch 3 with instructed people;
    CVMM and React from ``safe`` (see the module doc)."""
    if method != "SM2ITH":
        variant = "safe"
    return {
        (r["humans"], r["seed"]): float(r["success"] is True)
        for r in rows
        if (r["robot"], r["people"], r["method"], r["variant"])
        == ("stretch3", "instructed", method, variant)
    }


def _Cell(sm2ith, other, keys):
    e = PairedDifference([sm2ith[k] for k in keys], [other[k] for k in keys])
    return f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"


def main():
    for label, path in SOURCES.items():
        rows = ReadRows(path)
        for variant in ("safe", "paper"):
            s = Success(rows, "SM2ITH", variant)
            others = {m: Success(rows, m, variant) for m in ("CVMM", "React")}
            PrintPaired(f"{label}, {variant}", s, others)


def PrintPaired(title, s, others):
    """Arrivals and SM²ITH's paired differences, pooled and per count:
    ``s`` and each of ``others`` map (count, seed) → 1.0 / 0.0."""
    keys = sorted(set(s).intersection(*others.values()))
    totals = " / ".join(
        f"{m} {int(sum(d[k] for k in keys))} ("
        + "/".join(str(int(sum(d[k] for k in keys if k[0] == c))) for c in COUNTS)
        + ")"
        for m, d in (("SM²ITH", s), *others.items())
    )
    print(f"\n{title}: {len(keys)} paired runs; arrivals {totals}")
    for count in (None, *COUNTS):
        ks = [k for k in keys if count is None or k[0] == count]
        name = "pooled" if count is None else f"{count} people"
        by = "  ".join(f"− {m} {_Cell(s, d, ks)}" for m, d in others.items())
        got = int(np.sum([s[k] for k in ks]))
        print(f"  {name:9s} SM²ITH {got:3d}/{len(ks)}  {by}")


if __name__ == "__main__":
    main()
