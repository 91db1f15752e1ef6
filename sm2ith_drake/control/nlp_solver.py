"""The nonlinear stage solver: the validation reference.

Each stage (eq. stmpc) is the full nonlinear problem in a MathematicalProgram
(built once, bounds updated per step) solved by SNOPT or IPOPT, with the same
functions and analytic Jacobians as the real-time iteration. Slower than
:class:`~sm2ith_drake.control.rti_solver.RtiStageSolver`, which it validates.
"""

from __future__ import annotations

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import IpoptSolver, MathematicalProgram, SnoptSolver

from sm2ith_drake.control.program import MpcProgram
from sm2ith_drake.control.stage_problem import (
    LexicographicBand,
    Stage,
    StageProblem,
    StageResult,
    TaskCost,
    TaskCostGradient,
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
        self._problem = StageProblem(program, stage)
        nv = program.layout.num_variables
        self._nv = nv
        prog = MathematicalProgram()
        self._z = prog.NewContinuousVariables(nv, "z")
        self._bounds = prog.AddBoundingBoxConstraint(
            np.full(nv, -np.inf), np.full(nv, np.inf), self._z
        )
        self._targets = {}
        self._cache = {"key": None, "point": None}
        # Shared constraints (eq. stmpc_sys_consts); their bounds are read
        # again at each solve (the joint rows' widen with the state).
        self._shared = [
            (
                prog.AddConstraint(
                    self._Wrap(group), lo, hi, self._z, description=group.name
                ),
                lo,
                hi,
            )
            for group, lo, hi in self._problem.shared_constraints
        ]
        # Lexicographic constraints (eq. stmpc_lex_constr), bounds set per solve.
        self._lex = {}
        for group in self._problem.lexicographic_groups:
            big = np.full(group.num_rows, np.inf)
            name = group.task.name
            self._lex[name] = prog.AddConstraint(
                self._Wrap(group), -big, big, self._z, description="lex:" + name
            )
        # J_ℓ + J_eff (eq. stmpc_cost).
        prog.AddCost(self._CostFunction, self._z, description="tasks")
        prog.AddQuadraticCost(
            np.diag(self._problem.effort_diagonal),
            self._problem.effort_linear,
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
        for group, scale in self._problem.cost_groups:
            g, vals = group.Eval(point)
            w = self._problem.CostWeights(group, scale)
            cost += TaskCost(w, g)
            if autodiff:
                grad += TaskCostGradient(group.DenseJacobian(vals, self._nv), w, g)
        if not autodiff:
            return cost
        return InitializeAutoDiff(
            np.array([cost]), (grad @ ExtractGradient(x))[None, :]
        )[0, 0]

    def Solve(
        self,
        point,
        *,
        lower,
        upper,
        lex_bounds: dict,
        linearizations=None,
        warm_token=None,
        guess=None,
        damping=1.0,
    ) -> StageResult:
        """Solves from ``point``. ``lex_bounds`` maps task names to |e*| + tol;
        ``linearizations``, ``warm_token``, ``guess`` and ``damping`` are
        unused (the RTI's)."""
        self._targets.clear()
        self._targets.update(point.targets)
        self._cache["key"] = None
        self._bounds.evaluator().set_bounds(lower, upper)
        for binding, lo, hi in self._shared:
            binding.evaluator().set_bounds(lo, hi)
        for name, binding in self._lex.items():
            binding.evaluator().set_bounds(*LexicographicBand(lex_bounds[name]))
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
