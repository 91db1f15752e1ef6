"""The size of a hard 10-person stage QP and the fill of its reduced KKT
matrix (README, The 10-person p99, fifteenth session).

    python ../lazy-rows/qp_settings.py dump ridgeback_ur10 12 1 rb12.pkl
    python kkt_fill.py rb12.pkl

PIQP's sparse_ldlt factors [P + ρI + GᵀWG, Aᵀ; A, −δI] each iteration;
here W is a random positive diagonal (its values do not change the
pattern) and SciPy's SuperLU with a minimum-degree ordering on A + Aᵀ
stands in for PIQP's own LDLᵀ to count the factor's nonzeros."""

import pickle
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

qps = pickle.load(open(sys.argv[1], "rb"))
rng = np.random.default_rng(0)
for d in qps[-12:]:
    P, A, G = d["P"], d["A"], d["G"]
    P = P + P.T - sp.diags(P.diagonal())
    n, me, mi = P.shape[0], A.shape[0], G.shape[0]
    W = sp.diags(rng.random(mi) + 0.5)
    H = (P + G.T @ W @ G + sp.eye(n)).tocsc()
    K = sp.bmat([[H, A.T], [A, -1e-6 * sp.eye(me)]]).tocsc()
    lu = sla.splu(
        K,
        permc_spec="MMD_AT_PLUS_A",
        diag_pivot_thresh=0,
        options=dict(SymmetricMode=True),
    )
    print(
        f"n {n}, equalities {me}, inequalities {mi}: reduced KKT nnz {K.nnz}, "
        f"factor nnz (L + U) / 2 ≈ {(lu.L.nnz + lu.U.nnz) // 2}"
    )
