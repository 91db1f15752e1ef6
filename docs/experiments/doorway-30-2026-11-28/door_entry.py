"""Where the robot is when an oncoming person first comes within reach of
it, in the Stretch 3 doorway with instructed people (this directory's
``doorway.csv``, the default controller, `safe`): each run re-simulated,
then, at the first instant a person who started beyond the door (y > 0)
is within ``REACH`` of the robot's surface, the base's y (the door is at
y = 0, the robot starts at −1.5), whether the base is then in the door's
mouth (y > ``MOUTH``), and the run's outcome; and over the ``AFTER``
seconds that follow, how far the base gets toward the goal (Δy) and how
much it turns (|Δθ|). Paired over the same seeds for SM²ITH, CVMM and
React.

    python docs/experiments/doorway-30-2026-11-28/door_entry.py [COUNT]

COUNT: the people count (default 2). Output: door_entry_{COUNT}p.txt.
"""

import runpy
import sys
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.statistics import PairedDifference
from sm2ith_drake.experiments.studies import STUDIES

HERE = Path(__file__).resolve().parent
TRACE = runpy.run_path(str(HERE.parent / "final-2026-11-28" / "trace.py"))
METHODS = ("SM2ITH", "CVMM", "React")
# An instructed person reacts to the robot within 1 m of it (centre to
# surface); REACH is that distance as a gap (surface to surface).
REACH = 1.0 - 0.3
# The base is in the door's mouth beyond this y (m).
MOUTH = -0.45
# The window after the person comes within reach (s).
AFTER = 2.0


def Entry(row):
    """(run_id, success, base y at the first oncoming person's reach, Δy
    and |Δθ| over the AFTER seconds that follow; nan if nobody oncoming
    came within reach)."""
    scenario = LoadRunScenario(SpecFromRow(STUDIES["doorway"], row))
    oncoming = np.array([h.start[1] > 0 for h in scenario.humans])
    _, t, x, _, _, _, gap = TRACE["Resimulate"](scenario)
    near = np.any((gap < REACH) & oncoming[None], axis=1)
    if not near.any():
        return row["run_id"], row["success"] is True, np.nan, np.nan, np.nan
    i = int(np.argmax(near))
    j = min(int(np.searchsorted(t, t[i] + AFTER)), len(t) - 1)
    turn = np.abs(np.diff(np.unwrap(x[i : j + 1, 2]))).sum()
    return (
        row["run_id"],
        row["success"] is True,
        float(x[i, 1]),
        float(x[j, 1] - x[i, 1]),
        float(turn),
    )


def main(count):
    rows = [
        r
        for r in ReadRows(HERE / "doorway.csv")
        if (r["robot"], r["people"], r["variant"], r["humans"])
        == ("stretch3", "instructed", "safe", count)
        and r["method"] in METHODS
    ]
    with Pool(2) as pool:
        out = pool.map(Entry, rows)
    by = {(r["method"], r["seed"]): o for r, o in zip(rows, out, strict=True)}
    seeds = sorted({r["seed"] for r in rows})
    print(
        f"Stretch 3 doorway, {count} instructed people, safe: the base's y when "
        f"an oncoming person first comes within {REACH:.1f} m of the robot "
        f"(mouth of the door: y > {MOUTH})"
    )
    mouth = {}
    for m in METHODS:
        ys = np.array([by[m, s][2] for s in seeds])
        ok = np.array([by[m, s][1] for s in seeds])
        inside = ys > MOUTH
        mouth[m] = inside.astype(float)
        reached = ~np.isnan(ys)
        print(
            f"  {m:6s} person reached in {reached.sum()}/{len(seeds)} runs; base y "
            f"median {np.nanmedian(ys):+.2f} m; in the mouth {inside.sum()} "
            f"(of them arrived {np.sum(inside & ok)}); not in it: arrived "
            f"{np.sum(~inside & ok)} of {np.sum(~inside)}"
        )
    print(f"  over the {AFTER:.0f} s after: the base's Δy and total |Δθ|, medians")
    for m in METHODS:
        ys = np.array([by[m, s][2] for s in seeds])
        groups = (("in the mouth", ys > MOUTH), ("before it", ys <= MOUTH))
        for name, group in groups:
            chosen = [s for s, g in zip(seeds, group, strict=True) if g]
            dy = np.array([by[m, s][3] for s in chosen])
            turn = np.array([by[m, s][4] for s in chosen])
            if len(dy):
                print(
                    f"    {m:6s} {name:12s} n {len(dy):2d}: Δy {np.median(dy):+.2f} m, "
                    f"|Δθ| {np.median(turn):.2f} rad"
                )
    for m in METHODS[1:]:
        e = PairedDifference(list(mouth["SM2ITH"]), list(mouth[m]))
        print(
            f"  in the mouth, SM²ITH − {m}: "
            f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
