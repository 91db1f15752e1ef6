"""PIQP's settings on 10-person stage QPs (README, Benchmark, 2026-11-29).

    python qp_settings.py dump ROBOT STEPS EVERY OUT.pkl
        every EVERY-th PIQP QP of ``sm2ith bench --humans 10``
    python qp_settings.py hard ROBOT STEPS MIN_ITER OUT.pkl
        the QPs of the one-pass bench that take more than MIN_ITER iterations
    python qp_settings.py eval FILE... -- SETTINGS...
        each settings dict (over the shipped ones) on every dumped QP: PIQP's
        iterations, time, and the largest change of the solution and of the
        objective against the first settings given

The QPs are dumped as PIQP gets them (the lazy rows left out), so a QP is
re-solved exactly as the controller posed it. Not a controller."""

import pickle
import sys
import time

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run.bench import RunBenchmark


def Dump(robot, steps, keep, out, rti_iterations=None):
    """Runs the bench; keeps the QPs ``keep(count, iterations)`` selects."""
    qps, count = [], [0]
    solve = pw.PiqpWorkspace._Solve

    def _Solve(self, qp, dropped=None, max_iterations=None):
        # The signature since 405d286 (qp: Solve's first seven arguments).
        x, status, iterations = solve(self, qp, dropped, max_iterations)
        count[0] += 1
        if keep(count[0], iterations):
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
                )
            )
        return x, status, iterations

    pw.PiqpWorkspace._Solve = _Solve
    RunBenchmark(robot=robot, humans=10, steps=steps, rti_iterations=rti_iterations)
    pw.PiqpWorkspace._Solve = solve
    with open(out, "wb") as f:
        pickle.dump(qps, f)
    print(f"{len(qps)} QPs of {count[0]} -> {out}")


def Solve(d, settings):
    piqp = pw.PiqpBuild("generic")
    solver = piqp.SparseSolver()
    values = dict(pw.PIQP_DEFAULT_SETTINGS, **settings)
    values.pop("instruction_set")
    for name, value in values.items():
        if name == "kkt_solver":
            value = getattr(piqp.KKTSolver, value)
        setattr(solver.settings, name, value)
    start = time.perf_counter()
    solver.setup(
        d["P"], d["q"], d["A"], d["b"], d["G"], d["h_l"], d["h_u"], d["x_l"], d["x_u"]
    )
    status = solver.solve()
    info = solver.result.info
    elapsed = time.perf_counter() - start
    return np.array(solver.result.x), status.name, info.iter, elapsed, info.primal_obj


def Eval(files, settings_list):
    qps = [d for f in files for d in pickle.load(open(f, "rb"))]
    first = None
    for text in settings_list:
        results = [Solve(d, eval(text)) for d in qps]  # noqa: S307 (a dict literal)
        iterations = np.array([r[2] for r in results])
        unsolved = sum(r[1] != "PIQP_SOLVED" for r in results)
        line = (
            f"{text}: {len(qps)} QPs, {iterations.sum()} iterations "
            f"(median {np.median(iterations):.0f}, max {iterations.max()}), "
            f"{sum(r[3] for r in results) * 1e3:.0f} ms, {unsolved} not solved"
        )
        if first is None:
            first = results
        else:
            dx = max(
                np.max(np.abs(r[0] - f[0])) for r, f in zip(results, first, strict=True)
            )
            dobj = max(
                abs(r[4] - f[4]) / max(1.0, abs(f[4]))
                for r, f in zip(results, first, strict=True)
            )
            line += f", solutions moved by up to {dx:.1e}, objectives {dobj:.1e} rel."
        if len(qps) <= 10:
            line += f"; per QP {iterations.tolist()}"
        print(line, flush=True)


if __name__ == "__main__":
    command, args = sys.argv[1], sys.argv[2:]
    if command == "dump":
        every = int(args[2])
        Dump(args[0], int(args[1]), lambda n, _: n % every == 0, args[3])
    elif command == "hard":
        least = int(args[2])
        Dump(args[0], int(args[1]), lambda _, it: it > least, args[3], 1)
    else:
        split = args.index("--")
        Eval(args[:split], args[split + 1 :])
