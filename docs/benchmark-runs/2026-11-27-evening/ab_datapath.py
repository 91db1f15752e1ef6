"""The HPIPM data path before (ba0843b) and after 277af44 on the same stage
QPs (those of 30 benchmark steps with 3 people), solved alternately, three
times each: the whole HpipmStageQp.Solve (the IPM is the same in both).

    git worktree add /tmp/wt_auto ba0843b
    python docs/benchmark-runs/2026-11-27-evening/ab_datapath.py
"""

import importlib.util
import time

import numpy as np

from sm2ith_drake.control import hpipm_stage_qp as hs
from sm2ith_drake.run.bench import RunBenchmark

OLD = "/tmp/wt_auto/sm2ith_drake/control/hpipm_workspace.py"


def main():
    spec = importlib.util.spec_from_file_location("old_hw", OLD)
    old = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(old)
    solve = hs.HpipmStageQp.Solve
    captured = []

    def Capture(self, *args, **kwargs):
        captured.append((self, args, kwargs))
        return solve(self, *args, **kwargs)

    for robot in ("ridgeback_ur10", "stretch3"):
        captured.clear()
        hs.HpipmStageQp.Solve = Capture
        RunBenchmark(robot=robot, humans=3, steps=30)
        hs.HpipmStageQp.Solve = solve
        olds, t_old, t_new = {}, [], []
        for _ in range(3):
            for new, args, kwargs in captured:
                o = olds.setdefault(id(new), None) or old._Structure(new.ws, new)
                olds[id(new)] = o
                t0 = time.perf_counter()
                old._Structure.Solve(o, *args, **kwargs)
                t1 = time.perf_counter()
                solve(new, *args, **kwargs)
                t_old.append(t1 - t0)
                t_new.append(time.perf_counter() - t1)
        t_old, t_new = np.array(t_old) * 1e3, np.array(t_new) * 1e3
        print(
            f"{robot}: {len(captured)} QPs x3, Solve median old "
            f"{np.median(t_old):.2f} ms, new {np.median(t_new):.2f} ms, "
            f"median paired difference {np.median(t_old - t_new):.2f} ms"
        )


if __name__ == "__main__":
    main()
