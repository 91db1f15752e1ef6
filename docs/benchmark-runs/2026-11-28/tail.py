"""The slowest control steps of a benchmark run and what they solved:
HPIPM's stage QPs (iterations, ms, warm or cold), PIQP solves (a QP
HPIPM's fast mode left unsolved, or a pattern auto hands to PIQP), and the
steps' wall times by the number of HPIPM QPs.

    python docs/benchmark-runs/2026-11-28/tail.py ridgeback_ur10 3 [YAML]
"""

import collections
import sys
import time

import numpy as np

from sm2ith_drake.control import hpipm_library as hl
from sm2ith_drake.control import mpc_controller as mc
from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run.bench import RunBenchmark

SOLVE, STEP, PIQP = hl.OcpQp.Solve, mc.MpcController.Step, pw.PiqpWorkspace.Solve


def main(robot, humans, text):
    current, piqp, steps = [], [], []

    def Solve(self, robust=False, warm=False):
        start = time.perf_counter()
        status, iterations = SOLVE(self, robust, warm)
        current.append((iterations, (time.perf_counter() - start) * 1e3, warm, status))
        return status, iterations

    def Piqp(self, *args, **kwargs):
        start = time.perf_counter()
        out = PIQP(self, *args, **kwargs)
        piqp.append(((time.perf_counter() - start) * 1e3, out[2]))
        return out

    def Step(self, *args, **kwargs):
        current.clear()
        piqp.clear()
        start = time.perf_counter()
        out = STEP(self, *args, **kwargs)
        steps.append(((time.perf_counter() - start) * 1e3, list(current), list(piqp)))
        return out

    hl.OcpQp.Solve, mc.MpcController.Step = Solve, Step
    pw.PiqpWorkspace.Solve = Piqp
    try:
        RunBenchmark(robot=robot, humans=humans, steps=200, scenario_text=text or "")
    finally:
        hl.OcpQp.Solve, mc.MpcController.Step = SOLVE, STEP
        pw.PiqpWorkspace.Solve = PIQP
    by = collections.defaultdict(list)
    for t, qps, _ in steps:
        by[len(qps)].append(t)
    for n in sorted(by):
        print(f"{n} HPIPM QPs: {len(by[n])} steps, median {np.median(by[n]):.1f} ms")
    order = np.argsort([-t for t, _, _ in steps])
    print("slowest steps (ms; HPIPM iterations/ms/warm per QP; PIQP ms/iterations):")
    for i in order[:10]:
        t, qps, pq = steps[i]
        hp = " ".join(f"{it}/{ms:.1f}/{'w' if w else 'c'}{'' if s == 'solved' else '!'}"
                      for it, ms, w, s in qps)  # fmt: skip
        pi = " ".join(f"{ms:.1f}/{it}" for ms, it in pq)
        print(f"  step {i}: {t:.1f}  HPIPM [{hp}]  PIQP [{pi}]")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3] if len(sys.argv) > 3 else None)
