"""HPIPM's iterations and time per stage QP by its place in the control
step (one pass: QPs 0, 1; two passes: 0–3), and the steps' wall times.

    python docs/benchmark-runs/2026-11-27-late/passes.py ridgeback_ur10 3
"""

import collections
import sys
import time

import numpy as np

from sm2ith_drake.control import hpipm_library as hl
from sm2ith_drake.control import mpc_controller as mc
from sm2ith_drake.run.bench import RunBenchmark

SOLVE, STEP = hl.OcpQp.Solve, mc.MpcController.Step


def main(robot, humans):
    current, steps = [], []

    def Solve(self, robust=False):
        start = time.perf_counter()
        status, iterations = SOLVE(self, robust)
        current.append((iterations, (time.perf_counter() - start) * 1e3))
        return status, iterations

    def Step(self, *args, **kwargs):
        current.clear()
        start = time.perf_counter()
        out = STEP(self, *args, **kwargs)
        steps.append(((time.perf_counter() - start) * 1e3, list(current)))
        return out

    hl.OcpQp.Solve, mc.MpcController.Step = Solve, Step
    try:
        RunBenchmark(robot=robot, humans=humans, steps=200)
    finally:
        hl.OcpQp.Solve, mc.MpcController.Step = SOLVE, STEP
    by = collections.defaultdict(list)
    for _, qps in steps:
        for i, qp in enumerate(qps):
            by[(len(qps), i)].append(qp)
    for key in sorted(by):
        v = np.array(by[key])
        print(
            f"{key} {len(v)} QPs: iterations {v[:, 0].mean():.1f}, "
            f"{v[:, 1].mean():.2f} ms, {v[:, 1].sum() / v[:, 0].sum():.3f} ms/iteration"
        )
    one = [t for t, q in steps if len(q) == 2]
    two = [t for t, q in steps if len(q) >= 4]
    print(f"one-pass steps {len(one)} median {np.median(one):.1f} ms; "
          f"two-pass {len(two)} median {np.median(two):.1f} ms")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
