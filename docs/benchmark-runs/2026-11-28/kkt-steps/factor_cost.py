"""Where PIQP's factorization time goes in the 10-person stage QPs.

    python dump_qps.py 0 20        # dumps the last 12 stage QPs to /tmp/qps_0.pkl
    python factor_cost.py /tmp/qps_0.pkl

Solves the last six dumped QPs with the shipped PIQP settings, then without
the DT-CBF rows' person columns, then without the DT-CBF rows, and prints
PIQP's iterations and its KKT factorization time per iteration (its own
timer). Not a controller: the changed QPs are only for the cost."""

import pickle
import sys
import time

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control.piqp_workspace import PIQP_DEFAULT_SETTINGS, PiqpBuild

piqp = PiqpBuild("generic")


def Run(d, G=None, drop_rows=None):
    G = d["G"] if G is None else G
    hl, hu = d["h_l"], d["h_u"]
    if drop_rows is not None:
        keep = ~drop_rows
        G, hl, hu = G[keep], hl[keep], hu[keep]
    s = piqp.SparseSolver()
    for k, v in PIQP_DEFAULT_SETTINGS.items():
        if k == "instruction_set":
            continue
        if k == "kkt_solver":
            v = getattr(piqp.KKTSolver, v)
        setattr(s.settings, k, v)
    s.settings.compute_timings = True
    t = time.perf_counter()
    s.setup(d["P"], d["q"], d["A"], d["b"], G, hl, hu, d["x_l"], d["x_u"])
    s.solve()
    info = s.result.info
    return (time.perf_counter() - t) * 1e3, info.iter, info.kkt_factor_time * 1e3


qps = pickle.load(open(sys.argv[1], "rb"))
d = qps[-1]
print(
    f"variables {d['P'].shape[0]}, equality rows {d['A'].shape[0]}, "
    f"inequality rows {d['G'].shape[0]}, nonzeros A {d['A'].nnz} G {d['G'].nnz}"
)
# The people's positions and actions: the columns of the people's dynamics
# rows p_{k+1} − p_k − Δt a_k, the last N·H·2 ORCA-KKT equality rows (N = 10,
# H = 10).
eq_labels = d["labels"][d["eq_rows"]]
kkt_eq = np.nonzero(eq_labels == "orca_kkt_equalities")[0]
A = d["A"].tocoo()
people = np.unique(A.col[np.isin(A.row, kkt_eq[-10 * 10 * 2 :])])
print(f"people's position and action columns: {people.size}")
for d in qps[-6:]:
    labels = d["labels"][d["in_rows"]]
    cbf = labels == "dt_cbf"
    G = d["G"].tocoo()
    keep = ~(cbf[G.row] & np.isin(G.col, people))
    G_np = sp.csc_matrix((G.data[keep], (G.row[keep], G.col[keep])), shape=G.shape)
    rows = []
    for name, result in (
        ("shipped", Run(d)),
        ("DT-CBF without person columns", Run(d, G=G_np)),
        ("without DT-CBF rows", Run(d, drop_rows=cbf)),
    ):
        ms, it, factor = result
        rows.append(f"{name}: {it} it, {factor / it:.3f} ms/it")
    print(" | ".join(rows))
