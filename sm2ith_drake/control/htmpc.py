"""Hierarchical task MPC (eqs. htmpc, stmpc) and the weighted-sum baseline.

The lexicographic problem is solved as a sequence of single-task MPCs: stage ℓ
minimizes J_ℓ + J_eff subject to the shared constraints and, for every higher
task i < ℓ, |e_i,k,p| ≤ |e*_i,k,p| + tol at every step k and component p, where
e*_i is task i's error at the stage-i solution (eq. stmpc_lex_constr).

Two solvers:

- :class:`RtiStageSolver` (default): real-time iteration. All groups are
  linearized at the warm start (the shifted previous plan), and each stage is
  one sparse QP (Gauss–Newton Hessian for the task costs) solved by PIQP in a
  workspace set up once and only updated afterwards. With one iteration per
  step every stage shares the linearization, so e*_i is the linearized error
  of stage i and the stage-i solution is feasible for every later stage: the
  hierarchy can never make a QP infeasible.
- :class:`NlpStageSolver`: the full nonlinear stage problems in
  MathematicalProgram (built once, bounds updated per step) with SNOPT or
  IPOPT, using the same functions and analytic Jacobians. Slower; the
  validation reference.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import piqp
import scipy.sparse as sp
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import IpoptSolver, MathematicalProgram, SnoptSolver, SolverOptions

from sm2ith_drake.control.groups import ConstraintGroup
from sm2ith_drake.control.program import MpcProgram
from sm2ith_drake.control.tasks import Task


@dataclass
class Stage:
    """One single-task MPC of the hierarchy (or the one weighted-sum problem)."""

    name: str
    # (task, weight multiplier) pairs in the cost.
    cost_tasks: list[tuple[Task, float]]
    # Higher-priority tasks held by lexicographic constraints.
    lexicographic_tasks: list[Task]


def MakeStages(tasks: list[Task], method: str) -> list[Stage]:
    """The stages of ``htmpc`` (one per task, in priority order) or of the
    ``weighted_sum`` baseline (one stage, W_ℓ J_ℓ summed)."""
    if method == "weighted_sum":
        return [Stage("weighted_sum", [(t, t.weighted_sum_weight) for t in tasks], [])]
    return [Stage(t.name, [(t, 1.0)], list(tasks[:i])) for i, t in enumerate(tasks)]


@dataclass
class StageResult:
    z: np.ndarray
    success: bool
    status: str
    iterations: int
    # Errors of every task of this and higher priority at this stage's
    # solution, by task name, shape (N, s) for k = 1..N. For the RTI these
    # are the linearized errors the lexicographic constraints act on.
    errors: dict = field(default_factory=dict)


@dataclass
class MpcSolution:
    """The outcome of one control step, held in the controller's state."""

    z: np.ndarray
    q: np.ndarray  # (N+1, n) planned configurations
    nu: np.ndarray  # (N+1, m)
    u: np.ndarray  # (N, m)
    p_WE: np.ndarray  # (N+1, 3) planned EE path
    success: bool
    status: str
    stages: list[StageResult]
    solve_time: float
    iterations: int
    # Predicted human positions (N+1, H, 2) and the human id of each slot
    # (−1: empty), when the program has a predictor.
    human_predictions: np.ndarray | None = None
    human_slot_ids: np.ndarray | None = None
    # RTI passes that produced z (1 for the NLP solvers).
    passes: int = 1


class _Qp:
    """A sparse QP with a fixed pattern in a persistent PIQP workspace.

    min ½ xᵀPx + cᵀx  s.t.  x_l ≤ x ≤ x_u,  A_eq x = b,  h_l ≤ G x ≤ h_u.

    PIQP (a proximal interior-point method) is used rather than an ADMM
    solver: the lexicographic constraints are tight two-sided bands, on which
    OSQP needed ~18 000 iterations (250 ms) for a stage that PIQP solves in
    ~15 iterations (2–3 ms), to 1e-8 instead of 1e-4.
    """

    def __init__(self, *, num_variables, p_pattern, a_pattern, equality_rows, settings):

        self._piqp = piqp
        self.n = num_variables
        self.settings = settings
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

    def _Matrix(self, a_values, block):
        perm, indices, indptr, rows = block
        return sp.csc_matrix((a_values[perm], indices, indptr), (rows, self.n))

    @property
    def p_pattern(self):
        """The (row, column) of every stored entry of P's upper triangle, in
        the order :meth:`Solve` expects its values."""
        return self._p_indices, self._p_cols

    def Solve(self, p_values, q, a_values, x_lower, x_upper, lower, upper):
        """Returns (x, status, iterations); x is None if nothing usable."""
        P = sp.csc_matrix((p_values, self._p_indices, self._p_indptr), (self.n, self.n))
        A = self._Matrix(a_values, self._blocks[0])
        G = self._Matrix(a_values, self._blocks[1])
        b = lower[self._eq_rows]
        h_l, h_u = lower[self._in_rows], upper[self._in_rows]
        try:
            if self._solver is None:
                solver = self._piqp.SparseSolver()
                for key, value in self.settings.items():
                    if key == "kkt_solver" and isinstance(value, str):
                        value = getattr(self._piqp.KKTSolver, value)
                    setattr(solver.settings, key, value)
                solver.setup(P, q, A, b, G, h_l, h_u, x_lower, x_upper)
                self._solver = solver
            else:
                self._solver.update(
                    P=P, c=q, A=A, b=b, G=G, h_l=h_l, h_u=h_u, x_l=x_lower, x_u=x_upper
                )
            status = self._solver.solve()
        except Exception as e:  # noqa: BLE001 (an invalid setting, a NaN)
            self._solver = None
            return None, f"qp error: {e}", 0
        result = self._solver.result
        name = status.name.removeprefix("PIQP_").lower()
        return np.array(result.x), name, int(result.info.iter)


# sparse_ldlt_eq_cond (equalities condensed into the KKT system) measured
# ~17 % faster than PIQP's default on the SM²ITH stage QPs. PIQP's default
# duality-gap tolerance (1e-8 absolute, 1e-9 relative) was the criterion that
# ended its iterations: at 1e-6 the SM²ITH stage QPs take ~21 % fewer
# iterations (21.4 → 16.9 on 124 QPs with 3 people), far tighter than the
# lexicographic tolerance (1e-3) needs.
_QP_DEFAULTS = dict(
    verbose=False,
    eps_abs=1e-6,
    eps_rel=1e-7,
    eps_duality_gap_abs=1e-6,
    eps_duality_gap_rel=1e-6,
    kkt_solver="sparse_ldlt_eq_cond",
)
# QP structures (workspaces) kept per stage for recent sparsity patterns.
_MAX_STRUCTURES = 4


def _Linearize(group: ConstraintGroup, point, num_variables):
    g, vals = group.Eval(point)
    Jz = np.bincount(group.rows, vals * point.z[group.cols], minlength=group.num_rows)
    # g(z) ≈ J z + c,  c = g(z̄) − J z̄.
    return vals, g - Jz


class RtiStageSolver:
    """Solves one stage as a sparse QP linearized at a point (see module doc)."""

    def __init__(
        self,
        program: MpcProgram,
        stage: Stage,
        qp_options: dict,
        proximal_weight: float = 1.0,
    ):
        self.program = program
        self.stage = stage
        self.proximal_weight = proximal_weight
        nv = program.layout.num_variables
        self._nv = nv
        self._shared = program.ConstraintGroups()
        self._lex = [program.task_groups[t.name] for t in stage.lexicographic_tasks]
        self._cost = [(program.task_groups[t.name], w) for t, w in stage.cost_tasks]
        self._settings = dict(_QP_DEFAULTS)
        self._settings.update(qp_options)
        # Built structures (QP workspace and index maps) by sparsity pattern:
        # the pattern changes only when the predictor's neighbour sets do, and
        # a few recent ones are kept so sets that switch back cost nothing.
        self._structures: dict = {}
        self._key = None
        self._UseStructure()

    def _UseStructure(self):
        key = self.program.PatternKey()
        if key == self._key:
            return
        structure = self._structures.pop(key, None) or self._BuildStructure()
        self._structures[key] = structure  # most recent last
        while len(self._structures) > _MAX_STRUCTURES:
            self._structures.pop(next(iter(self._structures)))
        self._key = key
        for name, value in structure.items():
            setattr(self, name, value)

    def _BuildStructure(self) -> dict:
        """The QP workspace and index maps for the groups' current patterns."""
        nv = self._nv
        # Constraint rows: shared groups, then lexicographic groups. A shared
        # group whose bounds are equal when the stage is built (dynamics,
        # predictor equalities) is an equality for good.
        rows, cols, equality, offset = [], [], [], 0
        for group, glo, ghi in self._shared:
            rows.append(group.rows + offset)
            cols.append(group.cols)
            if np.array_equal(glo, ghi):
                equality.append(offset + np.arange(group.num_rows))
            offset += group.num_rows
        for group in self._lex:
            rows.append(group.rows + offset)
            cols.append(group.cols)
            offset += group.num_rows
        a_pattern = (np.concatenate(rows), np.concatenate(cols))
        equality_rows = np.concatenate(equality) if equality else np.zeros(0, int)
        # P pattern: diagonal plus the structure of Jᵀ J of every cost group.
        prows, pcols = [np.arange(nv)], [np.arange(nv)]
        for group, _ in self._cost:
            S = sp.csr_matrix(
                (np.ones(group.rows.size), (group.rows, group.cols)),
                shape=(group.num_rows, nv),
            )
            S = (S.T @ S).tocoo()
            prows.append(S.row)
            pcols.append(S.col)
        p_pattern = (np.concatenate(prows), np.concatenate(pcols))
        qp = _Qp(
            num_variables=nv,
            p_pattern=p_pattern,
            a_pattern=a_pattern,
            equality_rows=equality_rows,
            settings=self._settings,
        )
        # The cost Hessian is only nonzero on the diagonal and among the
        # (few) columns the cost groups touch: it is assembled there, small
        # and dense, then gathered into P's pattern.
        cost_cols = np.unique(
            np.concatenate([g.cols for g, _ in self._cost] + [np.zeros(0, dtype=int)])
        )
        local = np.full(nv, -1)
        local[cost_cols] = np.arange(cost_cols.size)
        prow, pcol = qp.p_pattern
        p_row_local, p_col_local = local[prow], local[pcol]
        p_diag = prow == pcol
        return dict(
            _qp=qp,
            _cost_cols=cost_cols,
            _cost_local=[local[g.cols] for g, _ in self._cost],
            _p_row_local=p_row_local,
            _p_col_local=p_col_local,
            _p_in_cost=(p_row_local >= 0) & (p_col_local >= 0),
            _p_diag=p_diag,
            _p_diag_index=prow[p_diag],
        )

    def Solve(self, point, *, lower, upper, lex_bounds: dict, linearizations: dict):
        """One QP at ``point``. ``lex_bounds`` maps task names to |e*| + tol;
        ``linearizations`` caches (values, c) per group for this point."""
        program, nv = self.program, self._nv
        self._UseStructure()

        def lin(group):
            key = id(group)
            if key not in linearizations:
                linearizations[key] = _Linearize(group, point, nv)
            return linearizations[key]

        nc = self._cost_cols.size
        P_cost = np.zeros((nc, nc))
        q_cost = np.zeros(nc)
        for (group, scale), local in zip(self._cost, self._cost_local, strict=True):
            vals, c = lin(group)
            w = scale * group.task.StageWeights(program.layout.N).ravel()
            J = np.zeros((group.num_rows, nc))
            np.add.at(J, (group.rows, local), vals)
            WJ = w[:, None] * J
            P_cost += J.T @ WJ
            q_cost += WJ.T @ c
        rho = self.proximal_weight
        p_values = np.zeros(self._p_diag.size)
        p_values[self._p_in_cost] = P_cost[
            self._p_row_local[self._p_in_cost], self._p_col_local[self._p_in_cost]
        ]
        p_values[self._p_diag] += (program.effort_diagonal + rho)[self._p_diag_index]
        qvec = np.zeros(nv)
        qvec[self._cost_cols] = q_cost
        qvec -= rho * point.z
        qvec += program.linear_cost
        a_vals, lo, hi = [], [], []
        for group, glo, ghi in self._shared:
            vals, c = lin(group)
            a_vals.append(vals)
            lo.append(glo - c)
            hi.append(ghi - c)
        for group in self._lex:
            vals, c = lin(group)
            b = lex_bounds[group.task.name]
            a_vals.append(vals)
            lo.append(-b - c)
            hi.append(b - c)
        x, status, iters = self._qp.Solve(
            p_values,
            qvec,
            np.concatenate(a_vals),
            lower,
            upper,
            np.concatenate(lo),
            np.concatenate(hi),
        )
        success = status in ("solved",)
        errors = {}
        if x is not None and np.all(np.isfinite(x)):
            for group in self._lex + [g for g, _ in self._cost]:
                vals, c = lin(group)
                e = np.bincount(
                    group.rows, vals * x[group.cols], minlength=group.num_rows
                )
                errors[group.task.name] = (e + c).reshape(program.layout.N, -1)
        else:
            success = False
        return StageResult(
            z=x, success=success, status=status, iterations=iters, errors=errors
        )


class NlpStageSolver:
    """One stage as a nonlinear MathematicalProgram (built once) solved by
    SNOPT or IPOPT with analytic Jacobians (see module doc)."""

    def __init__(
        self, program: MpcProgram, stage: Stage, solver_name: str, solver_options
    ):

        self.program = program
        self.stage = stage
        self._solver = SnoptSolver() if solver_name == "snopt" else IpoptSolver()
        if not self._solver.available() or not self._solver.enabled():
            raise RuntimeError(f"solver {solver_name} is not available in this Drake")
        self._options = solver_options
        nv = program.layout.num_variables
        self._nv = nv
        prog = MathematicalProgram()
        self._z = prog.NewContinuousVariables(nv, "z")
        self._bounds = prog.AddBoundingBoxConstraint(
            np.full(nv, -np.inf), np.full(nv, np.inf), self._z
        )
        self._targets = {}
        self._cache = {"key": None, "point": None}
        for group, lo, hi in program.ConstraintGroups():
            prog.AddConstraint(
                self._Wrap(group), lo, hi, self._z, description=group.name
            )
        self._lex = {}
        for task in stage.lexicographic_tasks:
            group = program.task_groups[task.name]
            big = np.full(group.num_rows, np.inf)
            self._lex[task.name] = prog.AddConstraint(
                self._Wrap(group), -big, big, self._z, description="lex:" + task.name
            )
        self._cost_groups = [
            (program.task_groups[t.name], w) for t, w in stage.cost_tasks
        ]
        prog.AddCost(self._CostFunction, self._z, description="tasks")
        prog.AddQuadraticCost(
            np.diag(program.effort_diagonal),
            program.linear_cost,
            self._z,
            is_convex=True,
        )
        self._prog = prog

    def _Point(self, z):
        key = z.tobytes()
        if self._cache["key"] != key:
            self._cache["key"] = key
            self._cache["point"] = self.program.MakePoint(z.copy(), self._targets)
        return self._cache["point"]

    def _Wrap(self, group):

        nv = self._nv

        def f(x):
            if x.dtype == float:
                g, _ = group.Eval(self._Point(x))
                return g
            xv = ExtractValue(x).reshape(-1)
            g, vals = group.Eval(self._Point(xv))
            J = group.DenseJacobian(vals, nv)
            return InitializeAutoDiff(g, J @ ExtractGradient(x)).reshape(-1)

        return f

    def _CostFunction(self, x):

        autodiff = x.dtype != float
        xv = ExtractValue(x).reshape(-1) if autodiff else x
        point = self._Point(xv)
        cost, grad = 0.0, np.zeros(self._nv)
        for group, scale in self._cost_groups:
            g, vals = group.Eval(point)
            w = scale * group.task.StageWeights(self.program.layout.N).ravel()
            cost += 0.5 * np.sum(w * g * g)
            if autodiff:
                grad += group.DenseJacobian(vals, self._nv).T @ (w * g)
        if not autodiff:
            return cost
        return InitializeAutoDiff(
            np.array([cost]), (grad @ ExtractGradient(x))[None, :]
        )[0, 0]

    def Solve(self, point, *, lower, upper, lex_bounds: dict, linearizations=None):
        self._targets.clear()
        self._targets.update(point.targets)
        self._cache["key"] = None
        self._bounds.evaluator().set_bounds(lower, upper)
        for name, binding in self._lex.items():
            b = lex_bounds[name]
            binding.evaluator().set_bounds(-b, b)
        result = self._solver.Solve(self._prog, point.z, self._options)
        z = result.GetSolution(self._z)
        success = bool(result.is_success())
        errors = {}
        final = self.program.MakePoint(z, point.targets)
        for task in self.stage.lexicographic_tasks + [
            t for t, _ in self.stage.cost_tasks
        ]:
            g, _ = self.program.task_groups[task.name].Eval(final)
            errors[task.name] = g.reshape(self.program.layout.N, -1)
        return StageResult(
            z=z,
            success=success,
            status=str(result.get_solution_result()),
            iterations=-1,
            errors=errors,
        )


class HierarchicalSolver:
    """Solves the whole hierarchy (or the weighted sum) for one control step."""

    def __init__(
        self,
        program: MpcProgram,
        *,
        method: str = "htmpc",
        solver: str = "rti",
        solver_options=None,
        lexicographic_tolerance: float = 1e-3,
        rti_iterations: int = 1,
        rti_proximal_weight: float = 1.0,
    ):

        self.program = program
        self.method = method
        self.solver_name = solver
        self.tolerance = lexicographic_tolerance
        self.rti_iterations = max(1, int(rti_iterations))
        self.stages = MakeStages(program.tasks, method)
        options = solver_options if solver_options is not None else SolverOptions()
        if solver == "rti":
            qp_options = dict(options.options.get("PIQP", {}))
            self._solvers = [
                RtiStageSolver(program, s, qp_options, rti_proximal_weight)
                for s in self.stages
            ]
        else:
            self._solvers = [
                NlpStageSolver(program, s, solver, options) for s in self.stages
            ]

    def Solve(self, *, q0, nu0, targets: dict, z_guess: np.ndarray) -> MpcSolution:
        """Runs every stage in priority order from the initial guess.

        RTI: each of the ``rti_iterations`` passes linearizes once, at the
        previous pass's result, and solves the whole hierarchy on that one
        linearization, so every stage is feasible given the stage above it.
        A pass after the first that fails keeps the previous pass's plan. A
        stage below the first that fails leaves the plan of the stages above
        it (status "solved through ...": every hard constraint and the higher
        priorities hold; only the lower tasks go unoptimized for that step).
        """
        start = time.perf_counter()
        program = self.program
        lower, upper = program.VariableBounds(q0, nu0)
        passes = self.rti_iterations if self.solver_name == "rti" else 1
        z = z_guess
        passes_run = 0
        results: list[StageResult] = []
        success, status, iterations = True, "solved", 0
        for it in range(passes):
            if it > 0 and program.predictor is not None:
                # The next linearization point: this pass's robot plan with
                # the humans' exact responses to it (see Predictor.Restore).
                z = z.copy()
                program.predictor.Restore(z)
            point = program.MakePoint(z, targets)
            z_pass, ok, why, pass_results = self._SolveHierarchy(point, lower, upper)
            if iterations >= 0 and all(r.iterations >= 0 for r in pass_results):
                iterations += sum(r.iterations for r in pass_results)
            else:
                iterations = -1  # the NLP solvers do not report iterations
            if not ok:
                if it == 0:
                    success, status, results = False, why, pass_results
                break
            z, results, status = z_pass, pass_results, why
            passes_run = it + 1
        q, nu, u = program.layout.Split(z)
        kin = program.robot.CalcKinematics(q)
        predictor = program.predictor
        return MpcSolution(
            human_predictions=None if predictor is None else predictor.Predictions(z),
            human_slot_ids=None if predictor is None else predictor.slot_ids,
            z=z,
            q=q,
            nu=nu,
            u=u,
            p_WE=np.asarray(kin.p_WE),
            success=success,
            status=status,
            stages=results,
            solve_time=time.perf_counter() - start,
            iterations=int(iterations),
            passes=passes_run,
        )

    def _SolveHierarchy(self, point, lower, upper):
        """One pass of every stage at one linearization point."""
        linearizations: dict = {}
        lex_bounds: dict = {}
        results: list[StageResult] = []
        z = point.z
        for stage, solver in zip(self.stages, self._solvers, strict=True):
            result = solver.Solve(
                point,
                lower=lower,
                upper=upper,
                lex_bounds=lex_bounds,
                linearizations=linearizations,
            )
            results.append(result)
            if not result.success:
                why = f"stage '{stage.name}': {result.status}"
                if len(results) == 1:
                    return z, False, why, results
                # The plan of the stages above meets every hard constraint
                # (dynamics, limits, barriers) and their priorities; only
                # this and the lower tasks go unoptimized this step.
                previous = self.stages[len(results) - 2].name
                why = f"solved through '{previous}' ({why})"
                return z, True, why, results[:-1]
            z = result.z
            for task, _ in stage.cost_tasks:
                lex_bounds[task.name] = (
                    np.abs(result.errors[task.name]).ravel() + self.tolerance
                )
        return z, True, "solved", results
