"""Each 10-person stage QP that put lazy rows back, solved again two ways
beside the controller's solve (README, The 10-person p99, fifteenth
session): with every DT-CBF row from the start, and with the rows the
controller put back already in ("oracle"). Iterations, time (ms) and the
largest change of the solution. Not a controller.

    python variants.py ROBOT STEPS"""

import sys
import time

import numpy as np

from sm2ith_drake.control import hierarchy
from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run import bench

step = [0]
solve = pw.PiqpWorkspace.Solve


def Timed(workspace, args, kwargs, lazy, far):
    start = time.perf_counter()
    x, _, iterations = solve(
        workspace,
        *args,
        lazy_rows=None if lazy is None else lazy.copy(),
        far_rows=None if far is None else far.copy(),
        **kwargs,
    )
    return x, iterations, (time.perf_counter() - start) * 1e3


def Solve(self, *args, lazy_rows=None, far_rows=None, **kwargs):
    lazy0 = None if lazy_rows is None else lazy_rows.copy()
    far0 = None if far_rows is None else far_rows.copy()
    start = time.perf_counter()
    result = solve(self, *args, lazy_rows=lazy_rows, far_rows=far_rows, **kwargs)
    ms = (time.perf_counter() - start) * 1e3
    if lazy0 is not None and (lazy0 & ~lazy_rows).any():
        x_all, it_all, ms_all = Timed(self, args, kwargs, None, far0)
        x_in, it_in, ms_in = Timed(self, args, kwargs, lazy_rows.copy(), far0)
        print(
            f"step {step[0]} lazy: {result[2]} its {ms:.0f} ms | "
            f"all rows: {it_all} its {ms_all:.0f} ms "
            f"dx {np.abs(x_all - result[0]).max():.1e} | "
            f"oracle: {it_in} its {ms_in:.0f} ms "
            f"dx {np.abs(x_in - result[0]).max():.1e}",
            flush=True,
        )
    self.piqp_iterations = result[2]
    return result


step_solve = hierarchy.HierarchicalSolver.Solve


def StepSolve(self, *args, **kwargs):
    result = step_solve(self, *args, **kwargs)
    step[0] += 1
    return result


pw.PiqpWorkspace.Solve = Solve
hierarchy.HierarchicalSolver.Solve = StepSolve
bench.RunBenchmark(robot=sys.argv[1], humans=10, steps=int(sys.argv[2]))
