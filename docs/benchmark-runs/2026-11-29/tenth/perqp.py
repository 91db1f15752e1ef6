"""Every PIQP solve of ``sm2ith bench --humans H``'s steps, for the slowest
steps (README, Benchmark, 2026-11-29, tenth session). Not a controller.

    python perqp.py ROBOT H [SCENARIO_TEXT]

Prints the bench's median / p99, the slowest eight steps with each of their
PIQP solves (ms, iterations, status, variables, equality and inequality
rows), the steps over 200 ms and how many solves each step took."""

import collections
import sys
import time

import numpy as np

from sm2ith_drake.control import mpc_controller, piqp_workspace
from sm2ith_drake.run.bench import RunBenchmark

steps, current = [], []
solve = piqp_workspace.PiqpWorkspace._Solve
step = mpc_controller.MpcController.Step


def _Solve(self, p, q, a, x_l, x_u, lower, upper, dropped=None):
    start = time.perf_counter()
    result = solve(self, p, q, a, x_l, x_u, lower, upper, dropped)
    rows = self._in_rows.size
    if dropped is not None:
        rows = int((~dropped[self._in_rows]).sum())
    elapsed = time.perf_counter() - start
    current.append((elapsed, result[2], result[1], self.n, self._eq_rows.size, rows))
    return result


def Step(self, *args, **kwargs):
    current.clear()
    start = time.perf_counter()
    out = step(self, *args, **kwargs)
    steps.append((time.perf_counter() - start, list(current)))
    return out


piqp_workspace.PiqpWorkspace._Solve = _Solve
mpc_controller.MpcController.Step = Step
text = sys.argv[3] if len(sys.argv) > 3 else ""
r = RunBenchmark(
    robot=sys.argv[1], humans=int(sys.argv[2]), steps=200, scenario_text=text
)
print({k: round(r[k], 1) for k in ("median_ms", "p99_ms", "max_ms", "mean_iterations")})
ms = np.array([t for t, _ in steps]) * 1e3
for i in np.argsort(ms)[::-1][:8]:
    print(f"step {i} {ms[i]:.0f} ms, {len(steps[i][1])} PIQP solves")
    for t, it, status, n, eq, ineq in steps[i][1]:
        print(f"   {t * 1e3:.1f} ms {it} iterations {status} n={n} eq={eq} in={ineq}")
print("steps over 200 ms:", [(int(i), round(ms[i])) for i in np.nonzero(ms > 200)[0]])
print("PIQP solves per step:", dict(collections.Counter(len(q) for _, q in steps)))
