"""The Stretch 3 doorway at 30 seeds per count on the controller of 19b15d2
(lazy barrier rows in PIQP's QPs, ``controller.lazy_barrier_distance:
0.5``): e176d82's table (``../e176d82/summary.py``) with every SM²ITH run
re-run. SM²ITH's 5-person QPs go to PIQP, and in the doorway HPIPM hands
some of its 1–3-person QPs to PIQP too (a sampled 2-person run differed).

    D=docs/experiments/doorway-30-2026-11-28/19b15d2
    sm2ith experiment doorway --runs 30 --variant safe,paper \\
        --people instructed,orca,social_force --only doorway_stretch3 \\
        --methods SM2ITH --jobs 2 --out $D/sm2ith
    python $D/summary.py

(The 5-person runs were run first, with ``--only doorway_stretch3_5h``.)
CVMM's and React's runs are e176d82's; the final re-run on 19b15d2 re-ran
their 5-person runs at 10 seeds (CVMM arrives once less per variant,
``../../final-19b15d2/compare.txt``). Output: summary.txt.
"""

import importlib.util
from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location(
    "summary_e176d82", HERE.parent / "e176d82" / "summary.py"
)
BEFORE = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(BEFORE)
_rows = BEFORE.Rows


def Rows(directory, people, variant, method):
    """e176d82's runs of a cell, SM²ITH's from ``sm2ith``."""
    rows = _rows(directory, people, variant, method)
    if method == "SM2ITH":
        for r in ReadRows(HERE / "sm2ith" / "doorway.csv"):
            if (r["robot"], r["people"], r["variant"], r["method"]) == (
                "stretch3",
                people,
                variant,
                method,
            ):
                rows[(r["humans"], r["seed"])] = r
    return rows


if __name__ == "__main__":
    BEFORE.Rows = Rows
    BEFORE.HERE = HERE
    BEFORE.main()
