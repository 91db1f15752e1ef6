"""Why the steps of ``sm2ith bench --humans 10`` take a second SQP pass
(README, Benchmark, 2026-11-29, ninth session).

    python why_second_pass.py ROBOT

Counts, over the 200 steps and over the slowest tenth, what the pass rule
(HierarchicalSolver._Converged) found after the first pass: "ok" (no
second pass), "pred" (the people's predicted actions had not converged),
"safety" (the plan broke a nonlinear safety row)."""

import sys
import time
from collections import Counter

import numpy as np

from sm2ith_drake.control import hierarchy, mpc_controller
from sm2ith_drake.run.bench import RunBenchmark

steps, reasons = [], []
converged = hierarchy.HierarchicalSolver._Converged
step = mpc_controller.MpcController.Step


def _Converged(self, z, targets):
    result = converged(self, z, targets)
    reasons.append("ok" if result[0] else ("pred" if result[2] else "safety"))
    return result


def Step(self, *args, **kwargs):
    reasons.clear()
    start = time.perf_counter()
    out = step(self, *args, **kwargs)
    steps.append((time.perf_counter() - start, tuple(reasons)))
    return out


hierarchy.HierarchicalSolver._Converged = _Converged
mpc_controller.MpcController.Step = Step
RunBenchmark(robot=sys.argv[1], humans=10, steps=200)
print(sys.argv[1], "all steps:", dict(Counter(r for _, r in steps)))
slowest = np.percentile([t for t, _ in steps], 90)
print("  slowest tenth:", dict(Counter(r for t, r in steps if t >= slowest)))
