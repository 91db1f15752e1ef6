"""A 200-step bench's control steps split by SQP passes: the median and
p99 of all steps, of the one-pass and of the two-pass steps, with their
QP iterations, and the slowest steps.

    python steps.py ROBOT PEOPLE [SCENARIO_TEXT]

Run from outside the checkout with PYTHONPATH set to the code to measure.
"""

import sys

import numpy as np

from sm2ith_drake.run.bench import BenchmarkScenario, _Simulate


def main(robot, people, text=""):
    scenario = BenchmarkScenario(robot, people, "orca_kkt", "rti", None, text)
    log, _, _ = _Simulate(scenario, 200)
    records = [r for r in log.records if r.mode != "none"][:200]
    wall = np.array([r.wall_time for r in records]) * 1e3
    passes = np.array([r.passes for r in records])
    iterations = np.array([r.iterations for r in records])
    p95, p99 = np.percentile(wall, [95, 99])
    print(
        f"{robot} median {np.median(wall):.1f} p95 {p95:.1f} p99 {p99:.1f} "
        f"max {wall.max():.1f}"
    )
    for count in (1, 2):
        m = passes == count
        if m.any():
            print(
                f" passes {count}: {m.sum()} steps, "
                f"median {np.median(wall[m]):.1f} ms, "
                f"p90 {np.percentile(wall[m], 90):.1f} ms, "
                f"median iterations {np.median(iterations[m])}"
            )
    for i in np.argsort(wall)[::-1][:12]:
        print(
            f"  step {i} {wall[i]:.1f} ms, passes {passes[i]}, "
            f"iterations {iterations[i]}, {records[i].status}"
        )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), *sys.argv[3:])
