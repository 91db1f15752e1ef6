"""The hierarchical task MPC (eq. htmpc) and the weighted-sum baseline: one
control step solves every stage (eq. stmpc) in priority order.

After each stage the errors of its cost tasks at its solution become, through
:func:`~sm2ith_drake.control.stage_problem.LexicographicBounds`, the bounds
that every later stage must keep (eq. stmpc_lex_constr). Two stage solvers:

- :class:`~sm2ith_drake.control.rti_solver.RtiStageSolver` (default): the
  real-time iteration, one sparse QP per stage on one shared linearization;
- :class:`~sm2ith_drake.control.nlp_solver.NlpStageSolver`: the full
  nonlinear stage problems with SNOPT or IPOPT, the validation reference.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
from pydrake.solvers import SolverOptions

from sm2ith_drake.control.nlp_solver import NlpStageSolver
from sm2ith_drake.control.program import MpcProgram
from sm2ith_drake.control.rti_solver import RtiStageSolver
from sm2ith_drake.control.stage_problem import (
    LexicographicBounds,
    MakeStages,
    StageResult,
)
from sm2ith_drake.scenario import WARM_STARTS

# The status of a stage that the step's QP iteration budget left no
# iterations (HierarchicalSolver's qp_iteration_budget).
BUDGET_SPENT = "QP iteration budget spent"
# How the status of a step whose lower stages went unoptimized begins.
SOLVED_THROUGH = "solved through"


def SolvedThrough(status: str) -> bool:
    """Whether a step's status says its lower stages went unoptimized (a
    lower stage's QP failed, or the QP iteration budget ran out)."""
    return status.startswith(SOLVED_THROUGH)


@dataclass
class _StepTally:
    """One control step's QP iterations, over its passes: all of them (−1
    once a stage solver reports none: the NLP solvers) and PIQP's, which
    ``budget`` (ControllerConfig.qp_iteration_budget; None: none) caps."""

    budget: int | None
    iterations: int = 0
    piqp: int = 0

    def Add(self, result: StageResult) -> None:
        if self.iterations >= 0 and result.iterations >= 0:
            self.iterations += result.iterations
        else:
            self.iterations = -1
        self.piqp += result.piqp_iterations

    def Spent(self) -> bool:
        """Whether the budget is spent (never without one)."""
        return self.budget is not None and self.piqp >= self.budget

    def Cap(self, exempt: bool) -> dict:
        """The stage solver's keyword for what is left of the budget ({}:
        uncapped, without a budget or for an ``exempt`` stage)."""
        if self.budget is None or exempt:
            return {}
        return dict(max_iterations=self.budget - self.piqp)


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


class HierarchicalSolver:
    """Solves the whole hierarchy (or the weighted sum) for one control step.

    ``stage_solvers`` holds one stage solver per entry of ``stages``, in
    priority order. It is a declared seam: any object with the stage
    solvers' ``Solve(point, *, lower, upper, lex_bounds, linearizations,
    warm_token, guess, damping)``
    returning a :class:`StageResult` may replace an entry (tests use it to
    force a stage to fail).
    """

    def __init__(
        self,
        program: MpcProgram,
        *,
        method: str = "htmpc",
        solver: str = "rti",
        solver_options=None,
        lexicographic_tolerance: float = 1e-3,
        rti_iterations: int = 1,
        rti_proximal_weight: float | np.ndarray = 1.0,
        rti_prediction_tolerance: float = 0.0,
        rti_constraint_tolerance: float = 0.0,
        rti_early_pass_check: bool = False,
        rti_warm_start: str = "cold",
        rti_later_pass_damping: float = 1.0,
        qp_solver: str = "piqp",
        lazy_barrier_distance: float = 0.0,
        lazy_line_margin: float = 0.0,
        qp_iteration_budget: int = 0,
    ):
        self.program = program
        self.method = method
        self.solver_name = solver
        self.tolerance = lexicographic_tolerance
        self.rti_iterations = max(1, int(rti_iterations))
        self.rti_prediction_tolerance = float(rti_prediction_tolerance)
        self.rti_constraint_tolerance = float(rti_constraint_tolerance)
        self.rti_early_pass_check = bool(rti_early_pass_check)
        if rti_warm_start not in WARM_STARTS:
            raise ValueError(f"rti_warm_start must be one of {WARM_STARTS}")
        self.rti_warm_start = rti_warm_start
        self.rti_later_pass_damping = float(rti_later_pass_damping)
        # ControllerConfig.qp_iteration_budget (None: no budget; the NLP
        # solvers take none).
        self.qp_iteration_budget = (
            (int(qp_iteration_budget) or None) if solver == "rti" else None
        )
        self.stages = MakeStages(program.tasks, method)
        options = solver_options if solver_options is not None else SolverOptions()
        if solver == "rti":
            self.stage_solvers = [
                RtiStageSolver(
                    program,
                    s,
                    options,
                    rti_proximal_weight,
                    qp_solver=qp_solver,
                    lazy_barrier_distance=lazy_barrier_distance,
                    lazy_line_margin=lazy_line_margin,
                )
                for s in self.stages
            ]
        else:
            self.stage_solvers = [
                NlpStageSolver(program, s, solver, options) for s in self.stages
            ]

    def Solve(self, *, q0, nu0, targets: dict, z_guess: np.ndarray) -> MpcSolution:
        """Runs every stage in priority order from the initial guess.

        RTI: each of up to ``rti_iterations`` passes linearizes once, at
        the previous pass's result, and solves the whole hierarchy on that
        one linearization, so every stage is feasible given the stage above
        it. With ``rti_prediction_tolerance`` > 0, no further pass runs once
        a pass has converged (:meth:`_Converged`).
        A pass after the first that fails keeps the previous pass's plan. A
        stage below the first that fails leaves the plan of the stages above
        it (status "solved through ...": every hard constraint and the higher
        priorities hold; only the lower tasks go unoptimized for that step).
        With ``qp_iteration_budget``, every QP but the first pass's first
        gets what is left of the step's budget, and one that has nothing
        left fails that way.
        """
        start = time.perf_counter()
        program = self.program
        # State and input limits (eq. htmpc_limits), the initial state pinned
        # to the measured one (eq. htmpc_init).
        lower, upper = program.VariableBounds(q0, nu0)
        passes = self.rti_iterations if self.solver_name == "rti" else 1
        z = z_guess
        passes_run = 0
        results: list[StageResult] = []
        success, status = True, "solved"
        # The LinearizationPoint of the current z's robot plan, if the pass
        # rule has made one (its kinematics are reused, not recomputed).
        checked = None
        # rti_warm_start "passes": one token per control step, with which a
        # pass after the first starts each HPIPM stage QP from the previous
        # pass's solution of it.
        token = object() if self.rti_warm_start == "passes" else None
        # The proximal weight's factor in this pass: rti_later_pass_damping
        # for a pass that runs because the people's predicted actions had
        # not converged (it linearizes at their exact responses), else 1
        # (the first pass, and an ordinary SQP pass: after a safety
        # violation, with rti_prediction_tolerance 0, or nobody predicted).
        damping = 1.0
        # This step's QP iterations, every stage solved (a failed one's too).
        tally = _StepTally(self.qp_iteration_budget)
        for it in range(passes):
            if it > 0 and tally.Spent():
                break  # no budget left for another pass
            if it > 0 and program.predictor is not None:
                # The next linearization point: this pass's robot plan with
                # the humans' exact responses to it (see Predictor.Restore).
                z = z.copy()
                program.predictor.Restore(z)
            if checked is not None:
                # Restore changed the people's variables only.
                point = dataclasses.replace(checked, z=z)
            else:
                point = program.MakePoint(z, targets)
            checked = None
            # With the early check, a non-final pass may stop after its
            # first stage (``cut``: that stage's plan already fails the
            # pass rule; ``cut_point`` is its point if the rule made one).
            early = targets if self.rti_early_pass_check and it + 1 < passes else None
            for attempt in range(2):
                z_pass, ok, why, pass_results, cut, cut_point = self._SolveHierarchy(
                    point,
                    lower,
                    upper,
                    early_targets=early,
                    warm_token=token,
                    damping=damping,
                    tally=tally,
                    exempt_first=it == 0,
                )
                # The turn monitoring's bounds (SafetyConfig.turn_monitoring)
                # can leave the first pass infeasible (measured in doorway
                # jams: the people's linearized KKT rows cannot all be met
                # with the turn held); the step then goes without them.
                if ok or attempt or it or program.TurnBounds(q0, nu0) is None:
                    break
                lower, upper = program.VariableBounds(q0, nu0, turn=False)
            if not ok:
                if it == 0:
                    success, status, results = False, why, pass_results
                break
            z, results, status = z_pass, pass_results, why
            passes_run = it + 1
            if cut:  # (the early check: damped either way)
                checked = cut_point
                damping = self.rti_later_pass_damping
                continue
            if it + 1 < passes:
                converged, checked, predictions = self._Converged(z, targets)
                if converged:
                    break
                damping = self.rti_later_pass_damping if predictions else 1.0
        q, nu, u = program.layout.Split(z)
        kin = checked.kin if checked is not None else program.robot.CalcKinematics(q)
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
            iterations=int(tally.iterations),
            passes=passes_run,
        )

    def _Converged(self, z, targets):
        """Whether another pass can be skipped after one that produced z
        (ControllerConfig.rti_iterations): the predicted human actions agree
        with the people's model and the plan keeps the nonlinear safety
        rows, each within its tolerance. Never with tolerance 0, nor
        without people to predict: then every pass is an ordinary SQP
        iteration on the robot's tasks. Returns (converged, the
        LinearizationPoint of z if the safety check made one, whether the
        predicted human actions were what had not converged)."""
        predictor = self.program.predictor
        if self.rti_prediction_tolerance <= 0 or predictor is None:
            return False, None, False
        errors = predictor.PredictionErrors(z)
        if errors.size and errors.max() > self.rti_prediction_tolerance:
            return False, None, True
        point = self.program.MakePoint(z, targets)
        violation = self.program.SafetyViolation(point)
        return violation <= self.rti_constraint_tolerance, point, False

    def _SolveHierarchy(
        self,
        point,
        lower,
        upper,
        early_targets=None,
        warm_token=None,
        damping=1.0,
        tally=None,
        exempt_first=True,
    ):
        """One pass of every stage at one linearization point. With
        ``early_targets``, the pass rule (:meth:`_Converged`) is applied to
        the first stage's plan, and a plan that fails it ends the pass there.
        ``tally`` (a _StepTally) counts the stages' iterations and caps them
        at what is left of its budget; ``exempt_first``: the first stage is
        not capped.
        Returns (z, ok, status, results, cut, point): cut says the pass
        ended early, point is then the LinearizationPoint the rule made of
        z (or None)."""
        linearizations: dict = {}
        lex_bounds: dict = {}
        results: list[StageResult] = []
        z = point.z
        tally = tally if tally is not None else _StepTally(None)
        for stage, solver in zip(self.stages, self.stage_solvers, strict=True):
            cap = tally.Cap(exempt=exempt_first and not results)
            if cap and cap["max_iterations"] <= 0:
                result = StageResult(
                    z=None, success=False, status=BUDGET_SPENT, iterations=0
                )
            else:
                result = solver.Solve(
                    point,
                    lower=lower,
                    upper=upper,
                    lex_bounds=lex_bounds,
                    linearizations=linearizations,
                    warm_token=warm_token,
                    guess=point.z if self.rti_warm_start == "point" else None,
                    damping=damping,
                    **cap,
                )
            tally.Add(result)
            results.append(result)
            if not result.success:
                why = f"stage '{stage.name}': {result.status}"
                if len(results) == 1:
                    return z, False, why, results, False, None
                # The plan of the stages above meets every hard constraint
                # (dynamics, limits, barriers) and their priorities; only
                # this and the lower tasks go unoptimized this step.
                previous = self.stages[len(results) - 2].name
                why = f"{SOLVED_THROUGH} '{previous}' ({why})"
                return z, True, why, results[:-1], False, None
            z = result.z
            first_of_several = len(results) == 1 < len(self.stages)
            if early_targets is not None and first_of_several:
                converged, checked, _ = self._Converged(z, early_targets)
                if not converged:
                    why = f"{SOLVED_THROUGH} '{stage.name}'"
                    return z, True, why, results, True, checked
            # Eq. stmpc_lex_constr for every later stage.
            for task, _ in stage.cost_tasks:
                lex_bounds[task.name] = LexicographicBounds(
                    result.errors[task.name], self.tolerance
                )
        return z, True, "solved", results, False, None
