"""HPIPM's modes and interior-point arguments on the stage QPs of one
200-step benchmark run (captured, then each re-solved with one change):
mean / p99 / max iterations, QPs not solved, total time, and how far the
solutions move from the shipped arguments'.

    python docs/benchmark-runs/2026-11-27-late/modes.py ridgeback_ur10 3
"""

import sys
import time

import numpy as np

from sm2ith_drake.control import hpipm_stage_qp as hs
from sm2ith_drake.run.bench import RunBenchmark

SOLVE = hs.HpipmStageQp.Solve


def Capture(robot, humans):
    captured = []

    def Solve(self, *args, **kwargs):
        copies = tuple(np.array(a) if isinstance(a, np.ndarray) else a for a in args)
        captured.append((self, copies))
        return SOLVE(self, *args, **kwargs)

    hs.HpipmStageQp.Solve = Solve
    try:
        RunBenchmark(robot=robot, humans=humans, steps=200)
    finally:
        hs.HpipmStageQp.Solve = SOLVE
    return captured


def Run(captured, label, base=None):
    its, failed, start, zs = [], 0, time.perf_counter(), []
    for qp, args in captured:
        z, status, iterations = SOLVE(qp, *args, retry=False)
        its.append(iterations)
        failed += status != "solved"
        zs.append(z)
    its = np.array(its)
    line = (
        f"{label:24s} mean it {its.mean():5.1f} p99 {np.percentile(its, 99):4.0f} "
        f"max {its.max():3d} not solved {failed} "
        f"time {(time.perf_counter() - start) * 1e3:7.0f} ms"
    )
    if base is not None:
        d = [np.max(np.abs(a - b)) for a, b in zip(zs, base, strict=True)
             if a is not None and b is not None]  # fmt: skip
        line += f"  max |dz| median {np.median(d):.1e} max {np.max(d):.1e}"
    print(line)
    return zs


def main(robot, humans):
    captured = Capture(robot, humans)
    print(len(captured), "QPs")
    structures = {id(qp): qp for qp, _ in captured}.values()
    base = Run(captured, "shipped")
    variants = [("mode", m, None) for m in ("speed", "balance")] + [
        ("arg", key, value)
        for key, values in (
            ("iter_max", (35, 40)),
            ("split_step", (0,)),
            ("ric_alg", (0, 1)),
            ("t_lam_min", (1,)),
        )
        for value in values
    ]
    for kind, key, value in variants:
        for qp in structures:
            mode = key if kind == "mode" else qp.ws.mode
            qp.qp._ipm[0] = qp.qp._Ipm(mode, dict(qp.ws.settings))
            if kind == "arg":
                qp.qp._SetArgument(qp.qp._ipm[0][0], key, value)
        Run(captured, key if kind == "mode" else f"{key}={value}", base)
    for qp in structures:
        qp.qp._ipm[0] = qp.qp._Ipm(qp.ws.mode, dict(qp.ws.settings))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
