"""How much the Stretch 3 turns its base in the head-on runs (this
directory's adversarial.csv, cell headon_stretch3), re-simulated: per
method, the largest heading away from the goal's direction and the total
turning (the integral of |dθ|) while the person is within 2 m, beside the
run's progress share and time to goal.

    python docs/experiments/seeds-30-2026-11-28/headon_turns.py PEOPLE VARIANT
"""

import runpy
import sys
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.statistics import PairedDifference
from sm2ith_drake.experiments.studies import STUDIES

HERE = Path(__file__).parent
NEAR = 2.0  # m: the person's centre within 2 m of the robot's surface


def Turns(row, resimulate):
    scenario = LoadRunScenario(SpecFromRow(STUDIES["adversarial"], row))
    _, _, x, P, _, dist, _ = resimulate(scenario)
    near = dist.min(axis=1) <= NEAR
    theta = np.unwrap(x[:, 2])
    if not np.any(near):
        return 0.0, 0.0
    turning = np.abs(np.diff(theta))[near[1:]].sum()
    return float(np.abs(theta[near]).max()), float(turning)


def main(people, variant):
    resimulate = runpy.run_path(str(HERE.parent / "final-2026-11-28" / "trace.py"))[
        "Resimulate"
    ]
    rows = [
        r
        for r in ReadRows(HERE / "adversarial.csv")
        if r["status"] == "ok"
        and r["family"] == "headon"
        and r["people"] == people
        and r["variant"] == variant
    ]
    by = {(r["method"], r["seed"]): r for r in rows}
    seeds = sorted({s for _, s in by})
    out = {}
    print("seed  method  progress  time to goal  max |θ| (rad)  turning (rad)")
    for seed in seeds:
        for method in ("SM2ITH", "CVMM"):
            row = by[(method, seed)]
            heading, turning = Turns(row, resimulate)
            out[(method, seed)] = (heading, turning)
            print(
                f"{seed:4d}  {method:6s}  {row['progress_share']:.3f}     "
                f"{row['time_to_goal']:6.1f}        {heading:5.2f}          "
                f"{turning:5.2f}"
            )
    for i, name in enumerate(("max |θ|", "turning")):
        a = [out[("SM2ITH", s)][i] for s in seeds]
        b = [out[("CVMM", s)][i] for s in seeds]
        d = PairedDifference(a, b)
        print(
            f"{name}: SM²ITH median {np.median(a):.2f}, CVMM {np.median(b):.2f}; "
            f"SM²ITH − CVMM {d.value:+.2f} [{d.low:+.2f}, {d.high:+.2f}] rad (n={d.n})"
        )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
