"""The Stretch 3 doorway with instructed people, 30 seeds per person count,
with the stall recovery on for every method (``controller.recovery``, with
the current phase's tolerance, commit 0876804): SM²ITH against CVMM and
React with it, and each method with it against its own default runs (this
directory's ``doorway.csv``), paired on (count, seed), pooled and per count,
in each variant; the runs with contact; and how the failed runs end.

CVMM's and React's two variants are one controller (the guard changes
only SM²ITH's rows): with the recovery their `paper` and `safe` runs with
1–3 people are identical, 180 pairs of 180 (success, time to goal, gap,
final distance), so their `safe` runs with 5 people were not run and
their `paper` runs stand for both variants here.

    sm2ith experiment doorway --runs 30 --variant paper,safe --people instructed \\
        --only doorway_stretch3 --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/recovery-phase \\
        --scenario_text '{controller: {recovery: {enabled: true}}}'
    python docs/experiments/doorway-30-2026-11-28/recovery_phase.py
"""

import runpy
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
METHODS = ("SM2ITH", "CVMM", "React")
COUNTS = (1, 2, 3, 5)


def Runs(rows, method, variant):
    """(count, seed) → row, for the Stretch 3 with instructed people (CVMM
    and React: their `paper` runs, see the module doc)."""
    if method != "SM2ITH":
        variant = "paper"
    return {
        (r["humans"], r["seed"]): r
        for r in rows
        if (r["robot"], r["people"], r["method"], r["variant"])
        == ("stretch3", "instructed", method, variant)
    }


def Success(runs):
    return {k: float(r["success"] is True) for k, r in runs.items()}


def _AgainstDefault(with_recovery, default):
    """Each method with the recovery against its own default, pooled and
    per count: arrivals and the paired difference."""
    keys = sorted(set(with_recovery) & set(default))
    s, d = Success(with_recovery), Success(default)
    out = []
    for count in (None, *COUNTS):
        ks = [k for k in keys if count is None or k[0] == count]
        if not ks:
            continue
        e = PairedDifference([s[k] for k in ks], [d[k] for k in ks])
        name = "pooled" if count is None else f"{count}p"
        out.append(
            f"{name} {int(sum(s[k] for k in ks))} vs {int(sum(d[k] for k in ks))} "
            f"({e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}])"
        )
    return "; ".join(out)


def _Contacts(runs):
    hits = [r for r in runs.values() if r["collision"] is True]
    if not hits:
        return "0"
    closing = sum(r["robot_closing_contact"] is True for r in hits)
    depth = -min(r["min_human_gap"] for r in hits)
    return f"{len(hits)} ({closing} closing, deepest {depth * 1e3:.0f} mm)"


def _Failures(runs):
    """How the failed runs end: how many, their final distance to the goal
    (median), and how many stood > 10 s; the mean recovery steps of all."""
    failed = [r for r in runs.values() if r["success"] is not True]
    steps = np.mean([r["recovery_steps"] for r in runs.values()])
    if not failed:
        return f"0 failed; recovery steps per run {steps:.1f}"
    final = np.median([r["base_error_final"] for r in failed])
    frozen = sum(r["freezing_time"] > 10 for r in failed)
    return (
        f"{len(failed)} failed (final distance median {final:.2f} m, "
        f"{frozen} standing > 10 s); recovery steps per run {steps:.1f}"
    )


def main():
    earlier = runpy.run_path(str(HERE.parent / "auto-rerun" / "doorway30.py"))
    rec_rows = ReadRows(HERE / "recovery-phase" / "doorway.csv")
    default_rows = ReadRows(HERE / "doorway.csv")
    for variant in ("safe", "paper"):
        rec = {m: Runs(rec_rows, m, variant) for m in METHODS}
        default = {m: Runs(default_rows, m, variant) for m in METHODS}
        earlier["PrintPaired"](
            f"recovery on for every method, {variant}",
            Success(rec["SM2ITH"]),
            {m: Success(rec[m]) for m in METHODS[1:]},
        )
        print(f"  each method with the recovery against its default ({variant}):")
        for m in METHODS:
            print(f"    {m:6s} {_AgainstDefault(rec[m], default[m])}")
        print(
            "  runs with contact: "
            + ", ".join(f"{m} {_Contacts(rec[m])}" for m in METHODS)
        )
        for m in METHODS:
            print(f"  {m:6s} {_Failures(rec[m])}")


if __name__ == "__main__":
    main()
