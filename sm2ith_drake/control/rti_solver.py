"""The real-time-iteration stage solver (the default).

All groups are linearized at the warm start (the shifted previous plan), and
each stage (eq. stmpc) is one sparse QP, with the Gauss–Newton Hessian for the
task costs (eq. stmpc_cost), solved by PIQP in a workspace set up once and
only updated afterwards. With one iteration per step every stage shares the
linearization, so e*_i is the linearized error of stage i and the stage-i
solution is feasible for every later stage (eq. stmpc_lex_constr): the
hierarchy can never make a QP infeasible.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from sm2ith_drake.control.groups import ConstraintGroup
from sm2ith_drake.control.hpipm_library import Library, StageQpSolver
from sm2ith_drake.control.hpipm_workspace import CheckHpipmSettings, HpipmWorkspace
from sm2ith_drake.control.piqp_workspace import (
    PIQP_DEFAULT_SETTINGS,
    CheckPiqpSettings,
    PiqpWorkspace,
)
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.control.program import MpcProgram
from sm2ith_drake.control.stage_problem import (
    LexicographicBand,
    Stage,
    StageProblem,
    StageResult,
    TaskCostGaussNewton,
)

# QP structures (workspaces) kept per stage for recent sparsity patterns.
_MAX_STRUCTURES = 4


def QpSettings(solver_options) -> tuple[dict, dict]:
    """The rti QPs' settings from Drake SolverOptions (its entries "PIQP"
    and "HPIPM"), checked: (PIQP's over PIQP_DEFAULT_SETTINGS, with our
    ``reuse_workspace``; HPIPM's as given). Raises UserError naming a
    setting the solver does not take (see CheckPiqpSettings)."""
    options = solver_options.options
    piqp = dict(PIQP_DEFAULT_SETTINGS, **options.get("PIQP", {}))
    reuse = piqp.pop("reuse_workspace", False)
    piqp = CheckPiqpSettings(piqp)
    piqp["reuse_workspace"] = bool(reuse)
    return piqp, CheckHpipmSettings(options.get("HPIPM", {}))


def _Linearize(group: ConstraintGroup, point, num_variables):
    with PROFILER.Phase("linearize", group.name):
        g, vals = group.Eval(point)
        Jz = np.bincount(
            group.rows, vals * point.z[group.cols], minlength=group.num_rows
        )
    # g(z) ≈ J z + c,  c = g(z̄) − J z̄.
    return vals, g - Jz


class RtiStageSolver:
    """Solves one stage as a sparse QP linearized at a point (see module doc)."""

    def __init__(
        self,
        program: MpcProgram,
        stage: Stage,
        solver_options,
        proximal_weight: float | np.ndarray = 1.0,
        qp_solver: str = "piqp",
        lazy_barrier_distance: float = 0.0,
        lazy_line_margin: float = 0.0,
    ):
        self.program = program
        self.stage = stage
        self.proximal_weight = proximal_weight
        self._problem = StageProblem(program, stage)
        nv = program.layout.num_variables
        self._nv = nv
        self._shared = self._problem.shared_constraints
        self._lex = self._problem.lexicographic_groups
        self._cost = self._problem.cost_groups
        self._qp_solver = StageQpSolver(qp_solver)
        # The thresholds of the groups' FarRows, by ConstraintGroup.lazy_setting.
        self._lazy = dict(
            lazy_barrier_distance=float(lazy_barrier_distance),
            lazy_line_margin=float(lazy_line_margin),
        )
        # PIQP's settings (the solver_options entry "PIQP"), and HPIPM's
        # ("HPIPM") for qp_solver hpipm and auto.
        self._settings, self._hpipm_settings = QpSettings(solver_options)
        if qp_solver == "hpipm":
            Library()  # HpipmUnavailable, with what to install, if missing
        # Not a PIQP setting: whether to update one PIQP workspace instead of
        # setting one up per solve (PiqpWorkspace; off: reproducible runs).
        self._reuse_workspace = bool(self._settings.pop("reuse_workspace"))
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

    @PROFILER.Timed("qp_structure_build")
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
        pattern = dict(
            num_variables=nv,
            p_pattern=p_pattern,
            a_pattern=a_pattern,
            equality_rows=equality_rows,
        )
        if self._qp_solver in ("hpipm", "auto"):
            qp = HpipmWorkspace(
                **pattern,
                settings=self._hpipm_settings,
                roles=self.program.layout.Roles(),
                piqp_settings=self._settings if self._qp_solver == "auto" else None,
            )
        else:
            qp = PiqpWorkspace(
                **pattern,
                settings=self._settings,
                reuse_workspace=self._reuse_workspace,
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

    def _FarRows(self, group, point, linearizations):
        """The group's rows the QP may leave out and check at its solution
        (ConstraintGroup.FarRows at the controller setting the group's
        ``lazy_setting`` names) and the entries it may drop (FarEntries), once
        per point."""
        threshold = self._lazy.get(group.lazy_setting, 0.0)
        if threshold <= 0:
            return None, None
        key = ("far", id(group))
        if key not in linearizations:
            linearizations[key] = (
                group.FarRows(point, threshold),
                group.FarEntries(point, threshold),
            )
        return linearizations[key]

    @PROFILER.Timed("qp_assembly")
    def Solve(
        self,
        point,
        *,
        lower,
        upper,
        lex_bounds: dict,
        linearizations: dict,
        warm_token=None,
        guess=None,
        damping=1.0,
        max_iterations=None,
    ) -> StageResult:
        """One QP at ``point``. ``lex_bounds`` maps task names to |e*| + tol;
        ``linearizations`` caches (values, c) per group for this point;
        ``warm_token``, ``guess`` (a primal starting point over z): see
        HpipmStageQp.Solve; ``damping`` multiplies the proximal weight;
        ``max_iterations`` caps PIQP's iterations (see PiqpWorkspace.Solve)."""
        program, problem, nv = self.program, self._problem, self._nv
        self._UseStructure()

        def lin(group):
            key = id(group)
            if key not in linearizations:
                linearizations[key] = _Linearize(group, point, nv)
            return linearizations[key]

        # The task costs (eq. stmpc_cost), Gauss–Newton on the cost columns.
        nc = self._cost_cols.size
        P_cost = np.zeros((nc, nc))
        q_cost = np.zeros(nc)
        for (group, scale), local in zip(self._cost, self._cost_local, strict=True):
            vals, c = lin(group)
            w = problem.CostWeights(group, scale)
            J = np.zeros((group.num_rows, nc))
            np.add.at(J, (group.rows, local), vals)
            hessian, gradient = TaskCostGaussNewton(J, w, c)
            P_cost += hessian
            q_cost += gradient
        # J_eff and the proximal term ½ Σ ρ_i (z_i − z̄_i)² (ρ per variable:
        # MpcProgram.ProximalMask).
        rho = self.proximal_weight * damping
        p_values = np.zeros(self._p_diag.size)
        p_values[self._p_in_cost] = P_cost[
            self._p_row_local[self._p_in_cost], self._p_col_local[self._p_in_cost]
        ]
        p_values[self._p_diag] += (problem.effort_diagonal + rho)[self._p_diag_index]
        qvec = np.zeros(nv)
        qvec[self._cost_cols] = q_cost
        qvec -= rho * point.z
        qvec += problem.effort_linear
        # Shared constraints (eq. stmpc_sys_consts), then the lexicographic
        # ones (eq. stmpc_lex_constr), both on the linearization J z + c.
        # Rows PIQP may leave out of every QP it solves (lazy) and of those
        # too wide for HPIPM only (wide), per group; entries it may drop.
        a_vals, lo, hi, lazy, wide, weak = [], [], [], [], [], []
        for group, glo, ghi in self._shared:
            vals, c = lin(group)
            a_vals.append(vals)
            lo.append(glo - c)
            hi.append(ghi - c)
            rows, entries = self._FarRows(group, point, linearizations)
            small = group.far_rows_in_small_qps
            lazy.append(rows if small else None)
            wide.append(None if small else rows)
            weak.append(entries)
        for group in self._lex:
            vals, c = lin(group)
            band_lo, band_hi = LexicographicBand(lex_bounds[group.task.name])
            a_vals.append(vals)
            lo.append(band_lo - c)
            hi.append(band_hi - c)
            lazy.append(None)
            wide.append(None)
            weak.append(None)
        lazy_rows, far_rows = _Concatenated(lazy, lo), _Concatenated(wide, lo)
        x, status, iters = self._qp.Solve(
            p_values,
            qvec,
            np.concatenate(a_vals),
            lower,
            upper,
            np.concatenate(lo),
            np.concatenate(hi),
            warm_token=warm_token,
            guess=guess,
            lazy_rows=lazy_rows,
            far_rows=far_rows,
            far_entries=_Concatenated(weak, a_vals),
            max_iterations=max_iterations,
        )
        # The rows the solve put back stay in the later QPs at this point
        # (the next stages: their plans are near this one's).
        for masks, solved in ((lazy, lazy_rows), (wide, far_rows)):
            if solved is not None:
                offset = 0
                for m, v in zip(masks, lo, strict=True):
                    if m is not None:
                        m &= solved[offset : offset + v.size]
                    offset += v.size
        success = status in ("solved", "solved_inaccurate")
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
            z=x,
            success=success,
            status=status,
            iterations=iters,
            errors=errors,
            piqp_iterations=self._qp.piqp_iterations,
        )


def _Concatenated(masks, like):
    """The per-group bool ``masks`` (None: all False) over the concatenation
    of ``like``'s arrays, or None if none is set."""
    if not any(m is not None and m.any() for m in masks):
        return None
    return np.concatenate(
        [
            np.zeros(v.size, dtype=bool) if m is None else m
            for m, v in zip(masks, like, strict=True)
        ]
    )
