"""Dumps every EVERY-th PIQP stage QP of the 10-person bench (as PIQP gets
it: lazy rows left out, without stored zeros) (README, Benchmark,
fourteenth session):

    python dump_qps.py ROBOT STEPS EVERY OUT.pkl
"""

import pickle
import sys

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run.bench import RunBenchmark

robot, steps, every, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
qps, count = [], [0]
solve = pw.PiqpWorkspace._Solve


def _Solve(self, qp, dropped=None, max_iterations=None):
    x, status, it = solve(self, qp, dropped, max_iterations)
    count[0] += 1
    if count[0] % every == 0:
        p, q, a, x_l, x_u, lower, upper = qp
        kept = np.ones(self._in_rows.size, dtype=bool)
        if dropped is not None:
            kept = ~dropped[self._in_rows]
        P = sp.csc_matrix((p, self._p_indices, self._p_indptr), (self.n, self.n))
        A = self._Matrix(a, self._blocks[0])
        G = pw._RowsOf(self._Matrix(a, self._blocks[1]), kept)
        P, A, G = (pw._WithoutZeros(M) for M in (P, A, G))
        qps.append(
            dict(
                P=P,
                q=np.array(q),
                A=A,
                b=lower[self._eq_rows].copy(),
                G=G,
                h_l=lower[self._in_rows][kept],
                h_u=upper[self._in_rows][kept],
                x_l=np.array(x_l),
                x_u=np.array(x_u),
                iterations=it,
                status=status,
            )
        )
    return x, status, it


pw.PiqpWorkspace._Solve = _Solve
RunBenchmark(robot=robot, humans=10, steps=steps)
pickle.dump(qps, open(out, "wb"))
print(len(qps), "of", count[0])
