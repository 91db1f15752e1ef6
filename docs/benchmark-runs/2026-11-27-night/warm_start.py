"""HPIPM's warm start measured on the stage QPs of 40 benchmark steps with
3 people (``sm2ith bench`` settings): every QP solved cold (as shipped),
then in the same order with ``warm_start`` 1 (the primal solution HPIPM
holds from the last solve of the same pattern as the starting point) and
2 (primal and dual). "same-step": the pattern was last solved in the same
control step (a second SQP pass); "cross-step": in an earlier step.

    python docs/benchmark-runs/2026-11-27-night/warm_start.py ridgeback_ur10
    python docs/benchmark-runs/2026-11-27-night/warm_start.py stretch3
"""

import ctypes
import sys

import numpy as np

from sm2ith_drake.control import hpipm_stage_qp as hs
from sm2ith_drake.control import mpc_controller as mc
from sm2ith_drake.run.bench import RunBenchmark

SOLVE = hs.HpipmStageQp.Solve
STEP = mc.MpcController.Step


def Capture(robot):
    """(step, stage QP object, arguments) of every HPIPM solve in order."""
    captured, step = [], [0]

    def Step(self, *args, **kwargs):
        step[0] += 1
        return STEP(self, *args, **kwargs)

    def Solve(self, *args, **kwargs):
        copies = tuple(np.array(a) if isinstance(a, np.ndarray) else a for a in args)
        captured.append((step[0], self, copies, kwargs))
        return SOLVE(self, *args, **kwargs)

    hs.HpipmStageQp.Solve, mc.MpcController.Step = Solve, Step
    try:
        RunBenchmark(robot=robot, humans=3, steps=40)
    finally:
        hs.HpipmStageQp.Solve, mc.MpcController.Step = SOLVE, STEP
    return captured


def SetWarmStart(qp, value):
    for arg, *_ in qp.qp._ipm:
        c_value = ctypes.c_int(value)
        qp.qp.lib.d_ocp_qp_ipm_arg_set(b"warm_start", ctypes.byref(c_value), arg)


def main(robot):
    captured = Capture(robot)
    cold = []
    for _, qp, args, kwargs in captured:
        SetWarmStart(qp, 0)
        z, _, iterations = SOLVE(qp, *args, **kwargs)
        cold.append((z.copy(), iterations))
    for mode in (1, 2):
        last_step, rows = {}, []
        for (step, qp, args, kwargs), (z_cold, it_cold) in zip(
            captured, cold, strict=True
        ):
            SetWarmStart(qp, mode)
            z, status, iterations = SOLVE(qp, *args, **kwargs)
            if id(qp) not in last_step:
                kind = "first"
            elif last_step[id(qp)] == step:
                kind = "same-step"
            else:
                kind = "cross-step"
            last_step[id(qp)] = step
            diff = np.max(np.abs(z - z_cold)) if z is not None else np.nan
            rows.append((kind, it_cold, iterations, diff, status))
        for kind in ("same-step", "cross-step", "first"):
            r = [x for x in rows if x[0] == kind]
            if not r:
                continue
            cold_it = np.mean([x[1] for x in r])
            warm_it = np.mean([x[2] for x in r])
            diffs = [x[3] for x in r]
            failed = sum(x[4] != "solved" for x in r)
            print(
                f"{robot} warm_start={mode} {kind}: {len(r)} QPs, iterations "
                f"cold {cold_it:.1f} warm {warm_it:.1f}, max |dz| median "
                f"{np.median(diffs):.1e} max {np.nanmax(diffs):.1e}, "
                f"not solved {failed}"
            )


if __name__ == "__main__":
    main(sys.argv[1])
