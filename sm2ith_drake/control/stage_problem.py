"""The lexicographic stage problem (eq. stmpc) that both stage solvers solve.

The lexicographic problem (eq. htmpc) is solved as a sequence of single-task
MPCs: stage ℓ minimizes J_ℓ + J_eff (eq. stmpc_cost) subject to the shared
constraints (eq. stmpc_sys_consts) and, for every higher task i < ℓ,
|e_i,k,p| ≤ |e*_i,k,p| + tol at every step k and component p, where e*_i is
task i's error at the stage-i solution (eq. stmpc_lex_constr). The tolerance
keeps the constraint feasible for a solver that meets e*_i only to its own
accuracy.

The task cost J_ℓ = ½ Σ_k ‖e_ℓ,k‖²_{W_k} and the lexicographic bounds are
written here once; :mod:`~sm2ith_drake.control.rti_solver` and
:mod:`~sm2ith_drake.control.nlp_solver` only choose how to solve them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

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
    # Of ``iterations``, PIQP's (what ControllerConfig.qp_iteration_budget
    # counts; HPIPM's QPs are capped by its own iter_max).
    piqp_iterations: int = 0


def LexicographicBounds(errors: np.ndarray, tolerance: float) -> np.ndarray:
    """|e*_i,k,p| + tol, flattened in row order: the bound that task i's
    error, found by its own stage, sets on every later stage (eq.
    stmpc_lex_constr)."""
    return np.abs(errors).ravel() + tolerance


def LexicographicBand(bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The constraint |e| ≤ b of eq. stmpc_lex_constr as −b ≤ e ≤ b."""
    return -bounds, bounds


def TaskCost(weights: np.ndarray, errors: np.ndarray) -> float:
    """½ Σ_k ‖e_k‖²_{W_k} (eq. stmpc_cost), errors and diagonal weights
    flattened alike."""
    return 0.5 * np.sum(weights * errors * errors)


def TaskCostGradient(
    jacobian: np.ndarray, weights: np.ndarray, errors: np.ndarray
) -> np.ndarray:
    """∇_z of :func:`TaskCost`: Jᵀ W e."""
    return jacobian.T @ (weights * errors)


def TaskCostGaussNewton(
    jacobian: np.ndarray, weights: np.ndarray, offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`TaskCost` of the linearized error e ≈ J z + c as ½ zᵀHz + gᵀz
    (+ const): returns (H, g) = (Jᵀ W J, Jᵀ W c), the Gauss–Newton model."""
    WJ = weights[:, None] * jacobian
    return jacobian.T @ WJ, WJ.T @ offset


class StageProblem:
    """Stage ℓ of eq. stmpc over one :class:`MpcProgram`: which groups are
    its cost, its shared constraints and its lexicographic constraints, and
    the weights of its cost.

    J_eff (eq. stmpc_cost) is the program's convex quadratic
    ½ zᵀ diag(effort_diagonal) z + linear_costᵀ z.
    """

    def __init__(self, program: MpcProgram, stage: Stage):
        self.program = program
        self.stage = stage
        # (group, lower, upper) of eq. stmpc_sys_consts (dynamics, eq.
        # htmpc_dyn; self-collision; the program's extra groups), fixed at
        # build. The limits and initial state (eqs. htmpc_limits,
        # htmpc_init) are the variable bounds, passed to each solve.
        self.shared_constraints = program.ConstraintGroups()
        # Groups of the tasks held by eq. stmpc_lex_constr, by priority.
        self.lexicographic_groups: list[ConstraintGroup] = [
            program.task_groups[t.name] for t in stage.lexicographic_tasks
        ]
        # (group, weight multiplier) of the task costs.
        self.cost_groups: list[tuple[ConstraintGroup, float]] = [
            (program.task_groups[t.name], w) for t, w in stage.cost_tasks
        ]

    def CostWeights(self, group: ConstraintGroup, scale: float) -> np.ndarray:
        """The diagonal of W_k (eq. stmpc_cost) for k = 1..N, flattened like
        the group's rows, times the stage's multiplier (1, or W_ℓ in the
        weighted-sum baseline)."""
        return scale * group.task.StageWeights(self.program.layout.N).ravel()

    @property
    def effort_diagonal(self) -> np.ndarray:
        """Hessian diagonal of J_eff."""
        return self.program.effort_diagonal

    @property
    def effort_linear(self) -> np.ndarray:
        """Linear term of J_eff."""
        return self.program.linear_cost
