"""Clarabel (QDLDL or faer's supernodal LDL) against PIQP on dumped
10-person stage QPs (README, Benchmark, 2026-11-29, tenth session).

    python clar.py DUMP.pkl METHOD        (METHOD: qdldl or faer)

DUMP.pkl from ``../lazy-rows/qp_settings.py dump`` / ``hard``. Clarabel is
not a dependency: install it aside (``pip install --target DIR
clarabel==0.11.1``, then PYTHONPATH=DIR)."""

import pickle
import sys
import time
from pathlib import Path

import clarabel
import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).parent.parent / "lazy-rows"))
from qp_settings import Solve  # noqa: E402


def Clarabel(d, method):
    P = sp.triu(d["P"]).tocsc()
    n = P.shape[0]
    G, h_l, h_u = d["G"].tocsr(), d["h_l"], d["h_u"]
    eye = sp.eye(n, format="csr")
    fu, fl = np.isfinite(h_u), np.isfinite(h_l)
    bu, bl = np.isfinite(d["x_u"]), np.isfinite(d["x_l"])
    A = sp.vstack([d["A"], G[fu], -G[fl], eye[bu], -eye[bl]]).tocsc()
    b = np.concatenate([d["b"], h_u[fu], -h_l[fl], d["x_u"][bu], -d["x_l"][bl]])
    rows = int(fu.sum() + fl.sum() + bu.sum() + bl.sum())
    cones = [clarabel.ZeroConeT(d["A"].shape[0]), clarabel.NonnegativeConeT(rows)]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.direct_solve_method = method
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-6
    start = time.perf_counter()
    solution = clarabel.DefaultSolver(P, d["q"], A, b, cones, settings).solve()
    elapsed = time.perf_counter() - start
    return np.array(solution.x), str(solution.status), solution.iterations, elapsed


qps = pickle.load(open(sys.argv[1], "rb"))
piqp = [Solve(d, {}) for d in qps]
clar = [Clarabel(d, sys.argv[2]) for d in qps]
moved = [np.max(np.abs(c[0] - p[0])) for c, p in zip(clar, piqp, strict=True)]
print(
    f"{len(qps)} QPs: PIQP {sum(p[3] for p in piqp) * 1e3:.0f} ms, "
    f"{sum(p[2] for p in piqp)} iterations; Clarabel ({sys.argv[2]}) "
    f"{sum(c[3] for c in clar) * 1e3:.0f} ms, {sum(c[2] for c in clar)} "
    f"iterations, {sum(c[1] != 'Solved' for c in clar)} not solved; "
    f"solutions apart by up to {max(moved):.1e}"
)
