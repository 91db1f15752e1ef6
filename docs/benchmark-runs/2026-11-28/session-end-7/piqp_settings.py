"""PIQP settings against the 10-person stage QPs that
``../kkt-steps/dump_qps.py`` dumps (``python dump_qps.py 0 20``: the last
12 QPs of 20 bench steps, Ridgeback–UR10, written to /tmp/qps_0.pkl):
the total PIQP iterations with each setting on top of the shipped ones,
and how far the solutions move.

    python piqp_settings.py

Output (2026-11-28): piqp_settings.txt.
"""

import pickle
from pathlib import Path

import numpy as np

from sm2ith_drake.control.piqp_workspace import PIQP_DEFAULT_SETTINGS, PiqpBuild

TRIED = [
    dict(preconditioner_iter=0),
    dict(preconditioner_iter=30),
    dict(preconditioner_scale_cost=True),
    dict(tau=0.995),
    dict(tau=0.9),
    dict(rho_init=1e-4),
    dict(delta_init=1e-2),
    dict(eps_duality_gap_rel=1e-5, eps_duality_gap_abs=1e-5),
]


def Solve(piqp, qp, extra):
    """(iterations, solution, status) of one dumped QP."""
    solver = piqp.SparseSolver()
    for key, value in (PIQP_DEFAULT_SETTINGS | extra).items():
        if key == "instruction_set":
            continue
        if key == "kkt_solver":
            value = getattr(piqp.KKTSolver, value)
        setattr(solver.settings, key, value)
    solver.setup(
        *(qp[k] for k in ("P", "q", "A", "b", "G", "h_l", "h_u", "x_l", "x_u"))
    )
    status = solver.solve()
    return solver.result.info.iter, np.array(solver.result.x), status.name


def main():
    qps = pickle.loads(Path("/tmp/qps_0.pkl").read_bytes())
    piqp = PiqpBuild("generic")
    base = [Solve(piqp, qp, {}) for qp in qps]
    print(f"shipped settings: {sum(b[0] for b in base)} iterations on {len(qps)} QPs")
    for extra in TRIED:
        runs = [Solve(piqp, qp, extra) for qp in qps]
        moved = max(np.abs(r[1] - b[1]).max() for r, b in zip(runs, base, strict=True))
        statuses = sorted({r[2] for r in runs})
        print(
            f"{extra}: {sum(r[0] for r in runs)} iterations, solutions moved by "
            f"up to {moved:.1e}, {statuses}"
        )


if __name__ == "__main__":
    main()
