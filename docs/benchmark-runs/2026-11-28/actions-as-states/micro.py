"""The HPIPM stage QPs of a 60-step bench, re-solved: the last 40 QPs,
each solved 15 times from the same data, the fastest kept (the machine's
noise mostly adds time). Prints the mean and median ms per QP, the mean
iterations and the mean ms per IPM iteration.

    python micro.py ROBOT PEOPLE     (e.g. ridgeback_ur10 3)

Run from outside the checkout with PYTHONPATH set to the code to measure.
"""

import sys
import time

import numpy as np

from sm2ith_drake.control import hpipm_stage_qp
from sm2ith_drake.run.bench import BenchmarkScenario, _Simulate


def main(robot, people):
    calls = []
    solve = hpipm_stage_qp.HpipmStageQp.Solve

    def Recorded(self, *args, **kwargs):
        calls.append((self, args, dict(kwargs)))
        return solve(self, *args, **kwargs)

    hpipm_stage_qp.HpipmStageQp.Solve = Recorded
    try:
        _Simulate(BenchmarkScenario(robot, people, "orca_kkt", "rti", None, ""), 60)
    finally:
        hpipm_stage_qp.HpipmStageQp.Solve = solve
    times, iterations = [], []
    for qp, args, kwargs in calls[-40:]:
        kwargs["warm_token"] = None
        best = np.inf
        for _ in range(15):
            start = time.perf_counter()
            _, _, count = qp.Solve(*args, **kwargs)
            best = min(best, time.perf_counter() - start)
        times.append(best * 1e3)
        iterations.append(count)
    times, iterations = np.array(times), np.array(iterations)
    print(
        f"per QP min-of-15 ms: mean {times.mean():.3f} median {np.median(times):.3f}; "
        f"iterations mean {iterations.mean():.1f}; "
        f"ms/iter {(times / iterations).mean():.4f}"
    )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
