"""The Stretch 3 doorway at 30 seeds per count on the controller of 19b15d2
(lazy barrier rows in PIQP's QPs, ``controller.lazy_barrier_distance:
0.5``): e176d82's table (``../e176d82/summary.py``) with SM²ITH's 5-person
runs, the only ones whose QPs go to PIQP, re-run.

    D=docs/experiments/doorway-30-2026-11-28/19b15d2
    sm2ith experiment doorway --runs 30 --variant safe,paper \\
        --people instructed,orca,social_force --only doorway_stretch3_5h \\
        --methods SM2ITH --jobs 2 --out $D/5p
    python $D/summary.py

CVMM's and React's QPs stay with HPIPM at 5 people (their people are not
variables); the final re-run on 19b15d2 re-ran them at 10 seeds and
compares them with e176d82's (``../../final-19b15d2/compare.txt``).
Output: summary.txt.
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
    """e176d82's runs of a cell, SM²ITH's 5-person ones from ``5p``."""
    rows = _rows(directory, people, variant, method)
    if method == "SM2ITH":
        for r in ReadRows(HERE / "5p" / "doorway.csv"):
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
