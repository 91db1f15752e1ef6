"""A sparse QP with a fixed sparsity pattern over PIQP, and the PIQP
settings the stage QPs use by default.

The pattern's index maps (CSC orderings, equality/inequality split) are built
once per pattern (see :class:`~sm2ith_drake.control.rti_solver.RtiStageSolver`);
each solve writes its values into them. PIQP itself is set up afresh for
every solve by default: a PIQP workspace that is ``update``d returns results
that depend on what it solved before (by ~1e-9), so a controller whose QPs
reuse one could not reproduce a run from a cloned Context, nor serve two
Contexts. Measured with 3 people (bench, Ridgeback–UR10, a loaded 2-core
machine): step medians within noise either way (150/156 and 189/184 ms
setup/update), PIQP's setups ~10 % of a step against ~5 % for updates.
``reuse_workspace=True`` keeps the old behaviour.

PIQP's wheel ships three builds of the same solver, generic, AVX2 and
AVX-512, and on import takes the widest the CPU has. The stage QPs are
small sparse LDLᵀ factorizations, which the wide vector units do not speed
up: on this project's machine (Xeon, AVX-512; 2026-11-27) the generic build
took 25–35 % less time per stage QP than the AVX-512 build PIQP picks
(captured Ridgeback–UR10 QPs, 3 people: 15.2–16.5 against 21.6 ms; 10
people 98–99 against 133 ms; Stretch 3, 3 people 11.7 against 14.5 ms; the
AVX2 build in between), in the same iterations, the solutions within 1e-8
(3 people). The setting ``instruction_set`` (not a PIQP setting) picks the
build: ``generic`` (the default), ``avx2``, ``avx512``, or ``auto`` (PIQP's
own choice).
"""

from __future__ import annotations

import importlib
from functools import cache

import numpy as np
import piqp
import scipy.sparse as sp

from sm2ith_drake.control.hpipm_library import Number
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.errors import UserError

# The builds inside PIQP's wheel, by the name the setting takes.
_PIQP_BUILDS = {
    "generic": "piqp_python",
    "avx2": "piqp_python_avx2",
    "avx512": "piqp_python_avx512",
}


@cache
def PiqpBuild(instruction_set: str):
    """The PIQP module of one build (see the module doc); ``auto`` is the
    one PIQP itself imports."""
    if instruction_set == "auto":
        return piqp
    name = _PIQP_BUILDS.get(instruction_set)
    if name is None:
        raise UserError(
            f"PIQP instruction_set {instruction_set!r}: one of "
            f"{', '.join(['auto', *_PIQP_BUILDS])}"
        )
    if name != "piqp_python" and not getattr(
        piqp.instruction_set, instruction_set.replace("avx512", "avx512f")
    ):
        raise UserError(f"PIQP instruction_set {instruction_set!r}: not on this CPU")
    try:
        return importlib.import_module(f"piqp.{name}")
    except ModuleNotFoundError as e:
        raise UserError(
            f"PIQP instruction_set {instruction_set!r}: this PIQP has no such "
            f"build ({e})"
        ) from e


def CheckPiqpSettings(settings: dict) -> dict:
    """The solver_options entry "PIQP" (PIQP's settings by name, and
    ``instruction_set``) checked against PIQP's own Settings: a number YAML
    read as text ("1e-4") becomes a number. UserError on a name PIQP does
    not have, a value of the wrong type (PIQP would reject it at every
    solve, and every step would fail) or a tolerance that is not a finite
    number (NaN or infinity, which PIQP would take)."""
    checked = dict(settings)
    build = PiqpBuild(checked.get("instruction_set", "generic"))
    probe = build.SparseSolver().settings
    for key, value in settings.items():
        if key == "instruction_set":
            continue
        if key.startswith("_") or not hasattr(probe, key):
            raise UserError(f"PIQP setting {key!r}: PIQP has no such setting")
        if key == "kkt_solver":
            if not isinstance(value, str) or not hasattr(build.KKTSolver, value):
                names = [k for k in dir(build.KKTSolver) if not k.startswith("_")]
                names = [k for k in names if k not in ("name", "value")]
                raise UserError(f"PIQP kkt_solver {value!r}: one of {', '.join(names)}")
            continue
        default = getattr(probe, key)
        if isinstance(default, float):
            # A finite number, or its text (a YAML "1e-4", not "nan").
            value = Number(f"PIQP setting {key!r}", value, float)
        try:
            setattr(probe, key, value)
        except TypeError:
            kind = {bool: "true or false", int: "a whole number"}.get(
                type(default), "a number"
            )
            raise UserError(f"PIQP setting {key!r}: {value!r} is not {kind}") from None
        checked[key] = value
    return checked


def _Entries(M: sp.csc_matrix, keep, rows, shape) -> sp.csc_matrix:
    """The stored entries ``keep`` (bool, per entry) of ``M`` with row
    indices ``rows`` (per entry), as a ``shape`` matrix in new arrays."""
    kept_before = np.concatenate([[0], np.cumsum(keep)])
    indptr = kept_before[M.indptr].astype(M.indptr.dtype)
    return sp.csc_matrix((M.data[keep], rows[keep], indptr), shape)


def _WithoutZeros(M: sp.csc_matrix) -> sp.csc_matrix:
    """``M`` without its stored zeros, in new arrays (``M`` shares its index
    arrays with the workspace's pattern, which must stay whole)."""
    return _Entries(M, M.data != 0, M.indices, M.shape)


def _RowsOf(M: sp.csc_matrix, kept: np.ndarray) -> sp.csc_matrix:
    """The rows ``kept`` (bool) of ``M``, in new arrays."""
    row = (np.cumsum(kept) - 1).astype(M.indices.dtype)
    return _Entries(M, kept[M.indices], row[M.indices], (int(kept.sum()), M.shape[1]))


class PiqpWorkspace:
    """A sparse QP with a fixed pattern, solved by PIQP.

    min ½ xᵀPx + cᵀx  s.t.  x_l ≤ x ≤ x_u,  A_eq x = b,  h_l ≤ G x ≤ h_u.

    PIQP (a proximal interior-point method) is used rather than an ADMM
    solver: the lexicographic constraints are tight two-sided bands, on which
    OSQP needed ~18 000 iterations (250 ms) for a stage that PIQP solves in
    ~15 iterations (2–3 ms), to 1e-8 instead of 1e-4.
    """

    def __init__(
        self,
        *,
        num_variables: int,
        p_pattern: tuple[np.ndarray, np.ndarray],
        a_pattern: tuple[np.ndarray, np.ndarray],
        equality_rows: np.ndarray,
        settings: dict,
        reuse_workspace: bool = False,
    ):
        """``p_pattern`` and ``a_pattern`` are the (row, column) of every
        entry of P and of the constraint matrix (COO, duplicates summed);
        ``equality_rows`` are the constraint rows with equal bounds;
        ``settings`` are PIQP settings by name (see
        :data:`PIQP_DEFAULT_SETTINGS`); ``reuse_workspace`` updates one PIQP
        workspace instead of setting one up per solve (module doc)."""
        self.n = num_variables
        self.reuse_workspace = reuse_workspace
        self.settings = dict(settings)
        self._piqp = PiqpBuild(self.settings.pop("instruction_set", "generic"))
        # P: upper triangle, CSC; values gathered from a dense matrix.
        rows, cols = p_pattern
        keep = rows <= cols
        Ps = sp.csc_matrix(
            (np.ones(keep.sum()), (rows[keep], cols[keep])), shape=(self.n, self.n)
        )
        Ps.sum_duplicates()
        Ps.sort_indices()
        self._p_indptr, self._p_indices = Ps.indptr, Ps.indices
        self._p_cols = np.repeat(np.arange(self.n), np.diff(Ps.indptr))
        # Constraint rows (COO order of the groups) split into equalities and
        # inequalities, each mapped to CSC order.
        arows, acols = a_pattern
        self._a_rows, self._a_cols = np.asarray(arows), np.asarray(acols)
        self.num_rows = int(arows.max()) + 1 if arows.size else 0
        eq = np.zeros(self.num_rows, dtype=bool)
        eq[equality_rows] = True
        self._eq_rows = np.nonzero(eq)[0]
        self._in_rows = np.nonzero(~eq)[0]
        self._blocks = []
        for sel in (self._eq_rows, self._in_rows):
            local = np.full(self.num_rows, -1)
            local[sel] = np.arange(sel.size)
            nz = np.nonzero(eq[arows] == (sel is self._eq_rows))[0]
            r, c = local[arows[nz]], acols[nz]
            order = np.lexsort((r, c))
            indptr = np.concatenate([[0], np.cumsum(np.bincount(c, minlength=self.n))])
            self._blocks.append((nz[order], r[order], indptr, sel.size))
        self._solver = None
        # The last Solve's iterations (as HpipmWorkspace.piqp_iterations).
        self.piqp_iterations = 0

    def _Matrix(self, a_values, block):
        perm, indices, indptr, rows = block
        return sp.csc_matrix((a_values[perm], indices, indptr), (rows, self.n))

    @property
    def p_pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """The (row, column) of every stored entry of P's upper triangle, in
        the order :meth:`Solve` expects its values."""
        return self._p_indices, self._p_cols

    @PROFILER.Timed("piqp")
    def Solve(
        self,
        p_values: np.ndarray,
        q: np.ndarray,
        a_values: np.ndarray,
        x_lower: np.ndarray,
        x_upper: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        warm_token=None,
        guess=None,
        lazy_rows=None,
        far_rows=None,
        far_entries=None,
        max_iterations=None,
    ) -> tuple[np.ndarray | None, str, int]:
        """Solves with P's values in :attr:`p_pattern` order, the constraint
        values in ``a_pattern`` order and the constraint rows' bounds
        ``lower`` ≤ row ≤ ``upper`` (equal on the equality rows).
        ``warm_token`` and ``guess`` are HpipmWorkspace's; PIQP always
        starts cold.

        ``lazy_rows`` (num_rows,) bool, optional: inequality rows that are
        left out of the QP and checked at its solution; those it violates,
        and those within LAZY_MARGIN of their bounds there, are put back
        (cleared in ``lazy_rows``, so that a later QP of the same rows
        starts with them) and the QP solved again (at most LAZY_ROUNDS
        times, then with every row). The solution is then the whole QP's (a
        solution of fewer rows that meets the others is optimal for all of
        them), in less time where the rows left out couple many variables
        (the DT-CBF rows of people far from the robot: PIQP's factorization
        fills in with each person's rows). A QP PIQP does not solve without
        the lazy rows is solved again with every row. An updated workspace
        (``reuse_workspace``) needs the fixed pattern: it keeps every row.

        ``far_rows`` (num_rows,) bool, optional: more rows left out and
        checked as ``lazy_rows`` are (ConstraintGroup.FarRows of the robot's
        lines, cleared where put back), and ``far_entries`` (a_values'
        size) bool: constraint entries solved as zeros
        (ConstraintGroup.FarEntries: an inexact Jacobian whose rows no
        longer couple a person's variables to the robot's, so the
        factorization does not fill in with them). A fixed pattern
        (``reuse_workspace``) keeps them. HpipmWorkspace passes both only
        for the QPs too wide for HPIPM, not for those its fast mode fails.

        ``max_iterations``, optional: PIQP's iterations over all the rounds
        (each round at most PIQP's ``max_iter``); a QP not solved within
        them fails (or counts as solved: see NearlySolved).

        Returns (x, status, iterations); x is None if nothing usable."""
        if far_entries is not None and not self.reuse_workspace:
            a_values = np.where(far_entries, 0.0, a_values)
        lazy = lazy_rows
        if far_rows is not None:
            lazy = far_rows if lazy_rows is None else lazy_rows | far_rows
        qp = (p_values, q, a_values, x_lower, x_upper, lower, upper)
        x, status, total = self._SolveLazily(qp, lazy, max_iterations)
        if lazy is not None and lazy is not lazy_rows and lazy is not far_rows:
            lazy_rows &= lazy
            far_rows &= lazy
        self.piqp_iterations = total
        return x, status, total

    def _SolveLazily(self, qp, lazy_rows, max_iterations):
        """Solve's rounds (see Solve); ``qp`` is its first seven arguments."""
        a_values, lower, upper = qp[2], qp[5], qp[6]
        lazy = None
        if lazy_rows is not None and not self.reuse_workspace:
            lazy = lazy_rows
            lazy[self._eq_rows] = False
        total = 0
        for round_ in range(LAZY_ROUNDS + 1):
            if lazy is not None and (not lazy.any() or round_ == LAZY_ROUNDS):
                lazy = None  # every row
            left = None if max_iterations is None else max_iterations - total
            if left is not None and left <= 0:
                return None, "max_iter_reached", total
            x, status, iterations = self._Solve(qp, lazy, left)
            total += iterations
            if lazy is None:
                return x, status, total
            if x is None or status not in ("solved", "solved_inaccurate"):
                # PIQP's path depends on the rows: a QP it does not solve
                # without the lazy rows it may solve with them (measured in
                # the doorway: 250 iterations without, 42–206 with every
                # row). The whole QP decides, in the next round.
                lazy = None
                continue
            in_lazy = lazy[self._a_rows]
            value = np.bincount(
                self._a_rows[in_lazy],
                a_values[in_lazy] * x[self._a_cols[in_lazy]],
                minlength=self.num_rows,
            )
            if not np.any(
                lazy
                & (
                    (value < lower - INACCURATE_PRIMAL)
                    | (value > upper + INACCURATE_PRIMAL)
                )
            ):
                return x, status, total
            lazy &= (value >= lower + LAZY_MARGIN) & (value <= upper - LAZY_MARGIN)

    def _Solve(self, qp, dropped=None, max_iterations=None):
        """One PIQP solve of the QP ``qp`` (Solve's first seven arguments)
        without the inequality rows ``dropped`` (num_rows,) bool (None: none;
        see Solve), in at most ``max_iterations`` (None: PIQP's
        ``max_iter``)."""
        p_values, q, a_values, x_lower, x_upper, lower, upper = qp
        P = sp.csc_matrix((p_values, self._p_indices, self._p_indptr), (self.n, self.n))
        A = self._Matrix(a_values, self._blocks[0])
        G = self._Matrix(a_values, self._blocks[1])
        if not self.reuse_workspace:
            # The fixed patterns store every entry that can be nonzero
            # somewhere (e.g. every joint of a person's nearest-body line);
            # at one point a quarter to a third of them are exactly zero.
            # PIQP factors stored zeros as nonzeros, so a fresh set-up gets
            # the matrices without them (~16 % less PIQP time with 3 people;
            # an updated workspace needs the fixed pattern).
            P, A, G = (_WithoutZeros(M) for M in (P, A, G))
        b = lower[self._eq_rows]
        h_l, h_u = lower[self._in_rows], upper[self._in_rows]
        if dropped is not None:
            kept = ~dropped[self._in_rows]
            G = _RowsOf(G, kept)
            h_l, h_u = h_l[kept], h_u[kept]
        try:
            if self._solver is None or not self.reuse_workspace:
                solver = self._piqp.SparseSolver()
                for key, value in self.settings.items():
                    if key == "kkt_solver" and isinstance(value, str):
                        value = getattr(self._piqp.KKTSolver, value)
                    setattr(solver.settings, key, value)
                self._max_iter = solver.settings.max_iter
                with PROFILER.Phase("piqp_setup"):
                    solver.setup(P, q, A, b, G, h_l, h_u, x_lower, x_upper)
                self._solver = solver
            else:
                self._solver.settings.max_iter = self._max_iter
                self._solver.update(
                    P=P, c=q, A=A, b=b, G=G, h_l=h_l, h_u=h_u, x_l=x_lower, x_u=x_upper
                )
            if max_iterations is not None:
                settings = self._solver.settings
                settings.max_iter = min(settings.max_iter, int(max_iterations))
            with PROFILER.Phase("piqp_solve"):
                timings = PROFILER.enabled
                if timings:
                    self._solver.settings.compute_timings = True
                status = self._solver.solve()
                if timings:
                    # PIQP's own timers: the KKT factorizations and the
                    # triangular solves of the solve's iterations.
                    info = self._solver.result.info
                    PROFILER.Record("piqp_kkt_factor", info.kkt_factor_time)
                    PROFILER.Record("piqp_kkt_solve", info.kkt_solve_time)
        except Exception as e:  # noqa: BLE001 (an invalid setting, a NaN)
            self._solver = None
            return None, f"qp error: {e}", 0
        result = self._solver.result
        name = status.name.removeprefix("PIQP_").lower()
        x = np.array(result.x)
        if name == "max_iter_reached" and NearlySolved(
            result.info, x, P, A, b, G, h_l, h_u, x_lower, x_upper
        ):
            name = "solved_inaccurate"
        return x, name, int(result.info.iter)


# A QP that reaches PIQP's iteration limit counts as solved
# ("solved_inaccurate") when its last iterate meets every constraint to
# within INACCURATE_PRIMAL (in the rows' own units: m, rad, m/s) and PIQP's
# relative duality gap is within INACCURATE_GAP and its relative dual
# residual within INACCURATE_DUAL. Measured on the doorway's failed solves
# (2026-11-28, 5 people, `base_position`): at 250 iterations every
# constraint held to 1e-9 and the gap was 1.5–3.8e-6 relative against
# PIQP's 1e-6, closing slowly under the walls' slack weight (1e6 per
# metre); the step braked although its plan was as good as solved.
INACCURATE_PRIMAL = 1e-6
INACCURATE_GAP = 1e-4
INACCURATE_DUAL = 1e-5

# How often PiqpWorkspace.Solve puts back lazy rows its solution violates
# before it solves with every row.
LAZY_ROUNDS = 2
# The rows put back with a violated lazy row: those within this of their
# bounds at the solution (in the rows' units; the DT-CBF's: m).
LAZY_MARGIN = 0.05


def NearlySolved(info, x, P, A, b, G, h_l, h_u, x_lower, x_upper) -> bool:
    """Whether PIQP's last iterate ``x`` of min ½xᵀPx + cᵀx s.t. Ax = b,
    h_l ≤ Gx ≤ h_u, x_l ≤ x ≤ x_u is a usable solution (see
    INACCURATE_PRIMAL): the constraints checked here on the problem's own
    data, the gap and dual residual from PIQP's ``info``."""
    if not np.all(np.isfinite(x)):
        return False
    if not (
        info.duality_gap_rel <= INACCURATE_GAP and info.dual_res_rel <= INACCURATE_DUAL
    ):
        return False
    gx = G @ x
    violation = max(
        np.max(np.abs(A @ x - b), initial=0.0),
        np.max(h_l - gx, initial=0.0),
        np.max(gx - h_u, initial=0.0),
        np.max(x_lower - x, initial=0.0),
        np.max(x - x_upper, initial=0.0),
    )
    return bool(violation <= INACCURATE_PRIMAL)


# PIQP's default KKT solver, sparse_ldlt, on matrices without stored zeros
# (PiqpWorkspace.Solve): on the stage QPs of 60 benchmark steps (PIQP 0.7)
# 20 % less time than sparse_ldlt_eq_cond with their stored zeros (the
# shipped setting until 2026-11-25) with 3 people, 18 % with 10; 4 % less
# than sparse_ldlt_eq_cond without them. Both solve the same QPs to within
# 1e-7 in the same iterations. PIQP's default
# duality-gap tolerance (1e-8 absolute, 1e-9 relative) was the criterion that
# ended its iterations: at 1e-6 the SM²ITH stage QPs take ~21 % fewer
# iterations (21.4 → 16.9 on 124 QPs with 3 people), far tighter than the
# lexicographic tolerance (1e-3) needs.
PIQP_DEFAULT_SETTINGS = dict(
    instruction_set="generic",
    verbose=False,
    eps_abs=1e-6,
    eps_rel=1e-7,
    eps_duality_gap_abs=1e-6,
    eps_duality_gap_rel=1e-6,
    kkt_solver="sparse_ldlt",
)
