"""The slowest control steps of ``sm2ith bench --humans 10``, with PIQP's
stage QPs in each (README, Benchmark, 2026-11-29).

    python trace_tail.py ROBOT STEPS RTI_ITERATIONS

Prints, for the ten slowest steps: the wall time, the stage QPs posed, the
PIQP solves they took (a lazy row put back costs one more) and each solve's
iterations."""

import sys
import time

import numpy as np

from sm2ith_drake.control import mpc_controller as mc
from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run.bench import RunBenchmark

steps, current = [], {}
solve, qp, step = pw.PiqpWorkspace._Solve, pw.PiqpWorkspace.Solve, mc.MpcController.Step


def _Solve(self, *args):
    x, status, iterations = solve(self, *args)
    current["iterations"].append(iterations)
    return x, status, iterations


def Qp(self, *args, **kwargs):
    current["qps"] += 1
    return qp(self, *args, **kwargs)


def Step(self, *args, **kwargs):
    current.update(qps=0, iterations=[])
    start = time.perf_counter()
    out = step(self, *args, **kwargs)
    steps.append(dict(current, ms=(time.perf_counter() - start) * 1e3))
    return out


pw.PiqpWorkspace._Solve, pw.PiqpWorkspace.Solve, mc.MpcController.Step = (
    _Solve,
    Qp,
    Step,
)
result = RunBenchmark(
    robot=sys.argv[1],
    humans=10,
    steps=int(sys.argv[2]),
    rti_iterations=int(sys.argv[3]),
)
print(f"median {result['median_ms']:.1f} ms, p99 {result['p99_ms']:.1f} ms")
print(
    f"median QP iterations {np.median(sum((s['iterations'] for s in steps), [])):.0f}"
)
for s in sorted(steps, key=lambda s: -s["ms"])[:10]:
    print(
        f"{s['ms']:.0f} ms: {s['qps']} QPs, {len(s['iterations'])} solves, "
        f"iterations {s['iterations']}"
    )
