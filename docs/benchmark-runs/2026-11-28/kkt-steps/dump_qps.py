"""Dumps the stage QPs PIQP solves in the 10-person benchmark
(Ridgeback–UR10, ``qp_solver: piqp``), for factor_cost.py.

    python dump_qps.py K STEPS    # K: prediction.kkt_steps (0: all)

Writes the last 12 stage QPs to /tmp/qps_K.pkl: PIQP's matrices as its
workspace hands them over (without stored zeros), the bounds, and the
constraint group of every row."""

import pickle
import sys

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.control import rti_solver as rs
from sm2ith_drake.run.bench import RunBenchmark

DUMPS = []
LABELS = {}  # number of variables -> the group name of every row
_solve = pw.PiqpWorkspace.Solve
_stage_solve = rs.RtiStageSolver.Solve


def Solve(self, p_values, q, a_values, x_lower, x_upper, lower, upper, **start):
    P = sp.csc_matrix((p_values, self._p_indices, self._p_indptr), (self.n, self.n))
    A = self._Matrix(a_values, self._blocks[0])
    G = self._Matrix(a_values, self._blocks[1])
    P, A, G = (pw._WithoutZeros(M) for M in (P, A, G))
    out = _solve(self, p_values, q, a_values, x_lower, x_upper, lower, upper, **start)
    DUMPS.append(
        dict(
            P=P,
            q=q.copy(),
            A=A,
            b=lower[self._eq_rows].copy(),
            G=G,
            h_l=lower[self._in_rows].copy(),
            h_u=upper[self._in_rows].copy(),
            x_l=x_lower.copy(),
            x_u=x_upper.copy(),
            eq_rows=self._eq_rows,
            in_rows=self._in_rows,
            iterations=out[2],
            labels=LABELS.get(self.n),
        )
    )
    return out


def StageSolve(self, point, **kwargs):
    """Records the group of every row (shared groups, then lexicographic)."""
    names = []
    for group, _, _ in self._shared:
        names += [group.name] * group.num_rows
    for group in self._lex:
        names += ["lex:" + group.task.name] * group.num_rows
    LABELS[self._nv] = np.array(names)
    return _stage_solve(self, point, **kwargs)


pw.PiqpWorkspace.Solve = Solve
rs.RtiStageSolver.Solve = StageSolve
K = int(sys.argv[1]) if len(sys.argv) > 1 else 0
steps = int(sys.argv[2]) if len(sys.argv) > 2 else 20
result = RunBenchmark(
    robot="ridgeback_ur10",
    humans=10,
    steps=steps,
    scenario_text=(
        f"{{prediction: {{kkt_steps: {K}}}, controller: {{qp_solver: piqp}}}}"
    ),
)
print(f"median {result['median_ms']:.1f} ms, {len(DUMPS)} QPs")
with open(f"/tmp/qps_{K}.pkl", "wb") as f:
    pickle.dump(DUMPS[-12:], f)
