"""The benchmark's slowest steps and what their stage QPs did (HPIPM
solved, HPIPM's fast mode not solved: PIQP then), with the scenario text
given (e.g. '{}' or '{safety: {guard_stopping_time: false}}').

    python docs/benchmark-runs/2026-11-27-night/slowest_steps.py '{}'
"""

import collections
import sys
import time

from sm2ith_drake.control import hpipm_stage_qp as hs
from sm2ith_drake.control import hpipm_workspace as hw
from sm2ith_drake.control import mpc_controller as mc
from sm2ith_drake.run.bench import RunBenchmark

stats = collections.Counter()
solve = hs.HpipmStageQp.Solve


def S(self, *a, **k):
    z, st, it = solve(self, *a, **k)
    stats["hpipm " + ("solved" if st == "solved" else "not solved")] += 1
    return z, st, it


build = hw.HpipmWorkspace._Build


def Bld(self, *a, **k):
    r = build(self, *a, **k)
    stats["build " + ("piqp" if r is hw._USE_PIQP else "hpipm")] += 1
    return r


step = mc.MpcController.Step
times = []


def St(self, *a, **k):
    before = dict(stats)
    t = time.perf_counter()
    r = step(self, *a, **k)
    times.append(
        (
            time.perf_counter() - t,
            {
                x: stats[x] - before.get(x, 0)
                for x in stats
                if stats[x] != before.get(x, 0)
            },
        )
    )
    return r


hs.HpipmStageQp.Solve, hw.HpipmWorkspace._Build, mc.MpcController.Step = S, Bld, St
RunBenchmark(robot="ridgeback_ur10", humans=3, steps=200, scenario_text=sys.argv[1])
print(sys.argv[1], dict(stats))
for t, d in sorted(times, key=lambda x: -x[0])[:6]:
    print(f"  {t * 1e3:.0f} ms {d}")
