"""The lazy rows' put-backs in ``sm2ith bench --humans 10`` (README,
Benchmark, 2026-11-29, tenth session). Not a controller.

    python lazytrace.py ROBOT [SCENARIO_TEXT]

For the first three steps and every step over 200 ms: each PIQP stage QP
solved with lazy rows, how many rows were left out, how many its solution
put back (then the QP is solved again), its iterations and time."""

import sys
import time

import numpy as np

from sm2ith_drake.control import mpc_controller, piqp_workspace
from sm2ith_drake.run.bench import RunBenchmark

log, steps = [], []
solve = piqp_workspace.PiqpWorkspace.Solve
step = mpc_controller.MpcController.Step


def Solve(self, *args, **kwargs):
    lazy = kwargs.get("lazy_rows")
    before = None if lazy is None else lazy.copy()
    start = time.perf_counter()
    result = solve(self, *args, **kwargs)
    if before is not None:
        back = before & ~lazy
        elapsed = time.perf_counter() - start
        log.append((len(steps), int(before.sum()), int(back.sum()), result[2], elapsed))
    return result


def Step(self, *args, **kwargs):
    start = time.perf_counter()
    out = step(self, *args, **kwargs)
    steps.append(time.perf_counter() - start)
    return out


piqp_workspace.PiqpWorkspace.Solve = Solve
mpc_controller.MpcController.Step = Step
text = sys.argv[2] if len(sys.argv) > 2 else ""
RunBenchmark(robot=sys.argv[1], humans=10, steps=200, scenario_text=text)
ms = np.array(steps) * 1e3
for k, left_out, put_back, iterations, elapsed in log:
    if ms[k] > 200 or k < 3:
        print(
            f"step {k} {ms[k]:.0f} ms: {left_out} rows left out, {put_back} put "
            f"back, {iterations} iterations, {elapsed * 1e3:.0f} ms"
        )
