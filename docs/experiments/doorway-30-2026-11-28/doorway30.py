"""The Stretch 3 doorway with instructed people, 30 seeds per person count,
on the final controller of 2026-11-28: SM²ITH against CVMM and React,
paired on (count, seed), pooled and per count, in each variant (every
method ran in both); beside it the 30-seed check of 2026-11-27 (``auto``,
``../qp-solver-auto/doorway/doorway.csv``, CVMM and React from ``safe``).

Seeds 0–9 are the final re-run's rows (``../final-2026-11-28``), copied;
seeds 10–29 were run here:

    sm2ith experiment doorway --runs 30 --variant paper,safe --people instructed \\
        --only doorway_stretch3 --jobs 2 --out docs/experiments/doorway-30-2026-11-28
    python docs/experiments/doorway-30-2026-11-28/doorway30.py
"""

import runpy
from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows

HERE = Path(__file__).resolve().parent
SOURCES = {
    "final 2026-11-28": (HERE / "doorway.csv", False),
    "auto 2026-11-27": (
        HERE.parent / "qp-solver-auto" / "doorway" / "doorway.csv",
        True,
    ),
}
METHODS = ("SM2ITH", "CVMM", "React")


def Outcomes(rows, method, variant, key):
    """(count, seed) → 1.0 / 0.0 of ``key`` for the Stretch 3 with
    instructed people."""
    return {
        (r["humans"], r["seed"]): float(r[key] is True)
        for r in rows
        if (r["robot"], r["people"], r["method"], r["variant"])
        == ("stretch3", "instructed", method, variant)
    }


def _Contacts(rows, variant):
    """Runs with contact (of them, with the robot closing in) and the
    deepest, per method."""
    out = []
    for m in METHODS:
        hits = [
            r
            for r in rows
            if (r["robot"], r["people"], r["method"], r["variant"])
            == ("stretch3", "instructed", m, variant)
            and r["collision"] is True
        ]
        closing = sum(r["robot_closing_contact"] is True for r in hits)
        if not hits:
            out.append(f"{m} 0")
            continue
        depth = -min(r["min_human_gap"] for r in hits)
        out.append(f"{m} {len(hits)} ({closing} closing, deepest {depth * 1e3:.0f} mm)")
    return ", ".join(out)


def main():
    # The 2026-11-27 check's script (its PrintPaired).
    earlier = runpy.run_path(str(HERE.parent / "auto-rerun" / "doorway30.py"))
    for label, (path, baselines_from_safe) in SOURCES.items():
        rows = ReadRows(path)
        for variant in ("safe", "paper"):
            base = "safe" if baselines_from_safe else variant
            s = Outcomes(rows, "SM2ITH", variant, "success")
            others = {m: Outcomes(rows, m, base, "success") for m in METHODS[1:]}
            earlier["PrintPaired"](f"{label}, {variant}", s, others)
            if not baselines_from_safe:
                print(f"  runs with contact: {_Contacts(rows, variant)}")


if __name__ == "__main__":
    main()
