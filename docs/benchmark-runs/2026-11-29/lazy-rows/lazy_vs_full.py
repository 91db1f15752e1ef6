"""The same 10-person stage QPs with every row, with the lazy rows removed,
and with them kept as zero rows with infinite bounds (README, How it works).

    python lazy_vs_full.py STEPS

Runs ``sm2ith bench --robot ridgeback_ur10 --humans 10`` for STEPS steps
(the default ``lazy_barrier_distance``), then re-solves every fifth of the
last 60 PIQP QPs that had rows left out the three ways and prints PIQP's
iterations and each solution's objective ½xᵀPx + qᵀx. Not a controller."""

import sys
import time

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run.bench import RunBenchmark

DUMPS = []
solve = pw.PiqpWorkspace._Solve


def _Solve(self, *args):
    if len(args) > 7 and args[7] is not None:
        DUMPS.append((self, [np.array(a, copy=True) for a in args]))
    return solve(self, *args)


pw.PiqpWorkspace._Solve = _Solve
RunBenchmark(robot="ridgeback_ur10", humans=10, steps=int(sys.argv[1]))
pw.PiqpWorkspace._Solve = solve
totals = {}
for ws, args in DUMPS[-60::5]:
    p, q, a, x_l, x_u, lower, upper, dropped = args
    Pu = sp.csc_matrix((p, ws._p_indices, ws._p_indptr), (ws.n, ws.n))
    P = Pu + Pu.T - sp.diags(Pu.diagonal())
    in_dropped = dropped[ws._a_rows]
    ways = {
        "every row": (a, lower, upper, None),
        "removed": (a, lower, upper, dropped),
        "zero rows": (
            np.where(in_dropped, 0.0, a),
            np.where(dropped, -np.inf, lower),
            np.where(dropped, np.inf, upper),
            None,
        ),
    }
    line, objectives = [], []
    for name, (values, lo, hi, rows) in ways.items():
        start = time.perf_counter()
        x, status, iterations = solve(ws, p, q, values, x_l, x_u, lo, hi, rows)
        elapsed = time.perf_counter() - start
        count, seconds = totals.get(name, (0, 0.0))
        totals[name] = (count + iterations, seconds + elapsed)
        objective = 0.5 * x @ (P @ x) + q @ x
        objectives.append(objective)
        line.append(f"{name} {iterations} it {status} {objective:.9e}")
    spread = (max(objectives) - min(objectives)) / max(1.0, abs(objectives[0]))
    print(" | ".join(line) + f" | objectives within {spread:.1e} rel.", flush=True)
for name, (count, seconds) in totals.items():
    print(f"{name}: {count} iterations, {seconds * 1e3:.0f} ms")
