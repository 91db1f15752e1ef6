"""PIQP factorization time per iteration on dumped QPs
(../lazy-rows/qp_settings.py dump) with the robot entries taken out of
kinds of inequality rows that tie a person to the robot (README,
Benchmark, fourteenth session). Not a controller: the QPs without those
entries are only timed.

    python fill_in.py QPS.pkl NQ NV        # Stretch 3: 7 6; Ridgeback-UR10: 9 9
"""

import pickle
import sys

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control import piqp_workspace as pw

qps = pickle.load(open(sys.argv[1], "rb"))
n, m, N = int(sys.argv[2]), int(sys.argv[3]), 10
R = (N + 1) * (n + m) + N * m


def run(d, G):
    s = pw.PiqpBuild("generic").SparseSolver()
    for k, v in pw.PIQP_DEFAULT_SETTINGS.items():
        if k == "instruction_set":
            continue
        if k == "kkt_solver":
            v = getattr(pw.PiqpBuild("generic").KKTSolver, v)
        setattr(s.settings, k, v)
    s.settings.compute_timings = True
    s.settings.max_iter = 15
    s.setup(d["P"], d["q"], d["A"], d["b"], G, d["h_l"], d["h_u"], d["x_l"], d["x_u"])
    s.solve()
    i = s.result.info
    return i.kkt_factor_time / i.iter * 1e3


def rowkind(G):
    G = G.tocsr()
    kind = np.zeros(G.shape[0], int)
    for i in range(G.shape[0]):
        c = G.indices[G.indptr[i] : G.indptr[i + 1]]
        rc = c[c < R]
        oc = c[c >= R]
        if rc.size == 0 or oc.size == 0:
            continue
        qk = len(set((rc[rc < (N + 1) * n] // n).tolist()))
        nuk = np.any((rc >= (N + 1) * n) & (rc < (N + 1) * (n + m)))
        kind[i] = 2 if qk == 2 else (1 if nuk else 3)
    return kind


def strip(G, rows):
    M = G.tocoo()
    keep = ~(rows[M.row] & (M.col < R))
    return sp.csc_matrix((M.data[keep], (M.row[keep], M.col[keep])), M.shape)


t = np.zeros(4)
for d in qps[5:25]:
    k = rowkind(d["G"])
    t += [
        run(d, d["G"]),
        run(d, strip(d["G"], k == 1)),
        run(d, strip(d["G"], k == 2)),
        run(d, strip(d["G"], (k == 1) | (k == 2))),
    ]
print(
    "factor ms/iter: base, KKT robot-line rows stripped, DT-CBF stripped, both:",
    np.round(t / 20, 3),
)
