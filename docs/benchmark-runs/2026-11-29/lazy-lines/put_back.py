"""How often PIQP solves a stage QP again for lazy rows it put back, per
group (README, Benchmark, fourteenth session):

    python put_back.py ROBOT STEPS YAML
"""

import collections
import sys

from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.control import rti_solver as rs
from sm2ith_drake.run.bench import RunBenchmark

stats = collections.Counter()
masks = {}
orig_far = rs.RtiStageSolver._FarRows


def _FarRows(self, group, point, lin):
    m = orig_far(self, group, point, lin)
    if m is not None:
        masks.setdefault(id(m), (group.name, m, int(m.sum())))
    return m


rs.RtiStageSolver._FarRows = _FarRows
orig_solve = rs.RtiStageSolver.Solve


def Solve(self, *a, **k):
    masks.clear()
    r = orig_solve(self, *a, **k)
    for name, m, n0 in masks.values():
        stats[name + " lazy"] += n0
        stats[name + " put back"] += n0 - int(m.sum())
        stats[name + " QPs with put back"] += int(m.sum() < n0)
    stats["QPs"] += 1
    return r


rs.RtiStageSolver.Solve = Solve
orig_lazy = pw.PiqpWorkspace._SolveLazily


def _SolveLazily(self, qp, lazy_rows, max_iterations):
    calls = [0]
    o = self._Solve

    def counting(*a, **k):
        calls[0] += 1
        return o(*a, **k)

    self._Solve = counting
    try:
        return orig_lazy(self, qp, lazy_rows, max_iterations)
    finally:
        del self._Solve
        stats[f"PIQP solves per QP {calls[0]}"] += 1


pw.PiqpWorkspace._SolveLazily = _SolveLazily
RunBenchmark(
    robot=sys.argv[1], humans=10, steps=int(sys.argv[2]), scenario_text=sys.argv[3]
)
for k, v in sorted(stats.items()):
    print(k, v)
