"""How far the robot closes in on people it touches, per run: every run of
a campaign CSV with ``robot_closing_contact``, re-simulated; the robot's own
part of the closing summed over the contact samples in which it closed in
(``robot_closing_distance``, RobotClosingContacts). Runs without
``robot_closing_contact`` closed in by 0. Campaign CSVs written since this
metric exist carry it; this measures it for the older ones.

    python docs/experiments/no-closer/closing.py CSV FILTER OUT [--jobs N]

Writes OUT (run_id, samples, closing_mm, largest_mm) and prints it.
"""

import csv
import sys
from multiprocessing import Pool

import numpy as np
from final_trace import TRACE, JobsOption

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.run.metrics import RobotClosingContacts


def Closing(row):
    scenario = LoadRunScenario(SpecFromRow(STUDIES[row["study"]], row))
    robot, _, x, P, _, dist, gap = TRACE.Resimulate(scenario)
    closing = RobotClosingContacts(robot, x, P, gap, dist)  # (T, H) m
    return (
        row["run_id"],
        int(np.any(closing > 0, axis=1).sum()),
        1e3 * float(closing.sum()),
        1e3 * float(closing.max(initial=0.0)),
    )


def main(argv):
    jobs, argv = JobsOption(argv)
    path, pattern, out = argv
    rows = [
        r
        for r in ReadRows(path)
        if pattern in r["run_id"] and r["robot_closing_contact"] is True
    ]
    with Pool(jobs) as pool:
        results = sorted(pool.map(Closing, rows))
    with open(out, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["run_id", "samples", "closing_mm", "largest_mm"])
        for run_id, n, total, largest in results:
            writer.writerow([run_id, n, f"{total:.2f}", f"{largest:.2f}"])
            print(f"{run_id}: {n} samples, {total:.1f} mm, largest {largest:.1f} mm")
    totals = [r[2] for r in results]
    if totals:
        print(
            f"{len(totals)} runs: median {np.median(totals):.1f} mm, "
            f"max {max(totals):.1f} mm, sum {sum(totals):.0f} mm"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
