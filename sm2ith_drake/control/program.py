"""One MPC program (eqs. htmpc and smith): variables, bounds, the shared
constraint groups and the effort cost.

The program is described once, as groups of vector-valued functions with a
fixed sparsity pattern (control/groups.py): each group evaluates its values
g(z̄) and the nonzeros of ∂g/∂z at a point z̄. Two stage solvers consume that
description: the real-time iteration (control/rti_solver.py), which
linearizes every group at the warm start and solves sparse QPs in a
persistent PIQP workspace, and the nonlinear path (control/nlp_solver.py),
which hands the same functions with their analytic Jacobians to SNOPT or
IPOPT through a MathematicalProgram.

Variables (eq. htmpc): q_0..q_N (configuration), ν_0..ν_N (pseudo-velocities)
and u_0..u_{N-1} = ν̇ (input). Predictors of human motion append their own
variables and groups (control/prediction/). The program holds:

- the robot dynamics (eqs. htmpc_dyn, smith_robdyn: DynamicsGroup);
- the state and input limits as variable bounds (eqs. htmpc_limits,
  smith_limits) and the initial condition pinned by bounds (eqs. htmpc_init,
  smith_init: VariableBounds), and the arm's limits between the knots
  (control/joint_limits.py);
- self-collision (eqs. htmpc_self_collision, smith_self_collision);
- the predictor's groups: for SM²ITH the human dynamics and the ORCA KKT
  system (eqs. smith_humdyn, smith_kkt_*; control/prediction/kkt_groups.py);
- the DT-CBF (eq. smith_avoid_coll; control/cbf.py);
- the effort J_eff of every stage's cost (eqs. htmpc_cost, smith_cost; the
  task terms are added per stage, control/stage_problem.py).
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.cbf import DtCbfGroup
from sm2ith_drake.control.groups import (
    ConstraintGroup,
    LinearizationPoint,
    VariableLayout,
)
from sm2ith_drake.control.joint_limits import (
    BrakingTrajectory,
    JointPeakGroup,
    WidenForBraking,
)
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.control.robot_groups import (
    DynamicsGroup,
    Rollout,
    SelfCollisionGroup,
    TaskErrorGroup,
)
from sm2ith_drake.control.separation import TurnLimits
from sm2ith_drake.control.tasks import Task
from sm2ith_drake.robots.planar_base import BaseStoppingTime
from sm2ith_drake.scenario import SafetyConfig

# Exact-penalty weights of constraint slacks (large against task costs of
# order 1 per metre of error). The barrier's are SafetyConfig's
# human_slack_weight and obstacle_slack_weight: a wall outranks a person's
# margin, so where a person crowds the robot against a wall the plan gives
# up the person's margin (0.1 m, still clear of them) before it enters the
# wall (measured in the doorway: with one weight for both a plan put a
# capsule 16 cm into the door jamb).
SLACK_LINEAR_WEIGHT = 1e3
SLACK_QUADRATIC_WEIGHT = 1e4


def GuardSteps(safety: SafetyConfig, robot, time_step: float) -> int:
    """The steps the guard holds (SafetyConfig.guard_steps, with
    guard_stopping_time at least the base's stopping time in steps)."""
    steps = int(safety.guard_steps)
    if safety.guard_stopping_time and steps > 0:
        steps = max(steps, NearSteps(robot, time_step))
    return steps


def NearSteps(robot, time_step: float) -> int:
    """The base's stopping time in steps, at least one: what
    SafetyConfig.no_closer_gap holds, and guard_stopping_time's least."""
    # (A hair of tolerance: 0.6 s of 0.2 s steps is 3 steps, not 4.)
    return max(1, int(np.ceil(BaseStoppingTime(robot) / time_step - 1e-9)))


class MpcProgram:
    """The groups and bounds shared by every stage of the hierarchy."""

    def __init__(
        self,
        *,
        robot,
        tasks: list[Task],
        horizon: int,
        time_step: float,
        self_collision_distance: float,
        effort_weight_nu: float,
        effort_weight_u: float,
        predictor=None,
        safety=None,
        obstacle_segments=None,
        joint_limits_between_knots=True,
    ):
        """``predictor`` (humans/predictors.py) adds the human variables and
        its constraints; with humans or ``obstacle_segments`` (S, 2, 2), the
        DT-CBF constraints of ``safety`` (a SafetyConfig) are added."""
        self.robot = robot
        self.tasks = list(tasks)
        self.time_step = time_step
        self.layout = VariableLayout(
            num_positions=robot.num_positions,
            num_velocities=robot.num_velocities,
            horizon=horizon,
        )
        L = self.layout
        self.dynamics = DynamicsGroup(robot, L, time_step)
        self.self_collision = SelfCollisionGroup(robot, L)
        self.self_collision_distance = self_collision_distance
        self.task_groups = {t.name: TaskErrorGroup(t, L) for t in self.tasks}
        # The arm's limits between the knots (control/joint_limits.py).
        self.joint_peaks = (
            JointPeakGroup(robot, L, time_step) if joint_limits_between_knots else None
        )
        # Extra groups from the human predictor and the DT-CBF safety
        # constraints: (group, lower, upper).
        self.extra_constraints: list[
            tuple[ConstraintGroup, np.ndarray, np.ndarray]
        ] = []
        self.predictor = predictor
        self.cbf = None
        segments = (
            np.zeros((0, 2, 2))
            if obstacle_segments is None
            else np.asarray(obstacle_segments, dtype=float).reshape(-1, 2, 2)
        )
        if predictor is not None:
            predictor.AddVariables(L)
            self.extra_constraints += predictor.ConstraintGroups(self)
        slots = predictor.num_slots if predictor is not None else 0
        extras = predictor.extra_active.size if predictor is not None else 0
        if slots or extras or len(segments):
            safety = safety or SafetyConfig()
            positions = (
                predictor.p
                if predictor is not None
                else np.zeros((L.N + 1, 0, 2), dtype=int)
            )
            self.cbf = DtCbfGroup(
                robot,
                L,
                positions,
                gamma=safety.gamma,
                human_radius=safety.human_radius,
                human_margin=safety.human_margin,
                obstacle_segments=segments,
                obstacle_margin=safety.obstacle_margin,
                # Only SM²ITH's interactive prediction is ever guarded
                # against people moving on (SafetyConfig.guard_deviation):
                # CVMM's prediction already is that motion.
                guard_steps=(
                    GuardSteps(safety, robot, time_step)
                    if predictor is not None
                    and predictor.name == "orca_kkt"
                    and safety.mode == "safe"
                    else 0
                ),
                # Every prediction that moves people is guarded against
                # them standing still (SafetyConfig.static_guard_steps);
                # React's barrier already is that, so React is the same
                # controller in both safety variants.
                static_guard_steps=(
                    safety.static_guard_steps
                    if predictor is not None
                    and predictor.name != "react"
                    and safety.mode == "safe"
                    else 0
                ),
                # People beyond the slots, at constant velocity (held for
                # React), in both safety variants.
                extra_humans=extras,
                inside=safety.inside_barrier,
                guard_gamma=safety.guard_gamma,
                guard_inside=safety.guard_inside,
                # SafetyConfig.no_closer_gap, `safe` only, every method
                # alike, over the base's stopping time.
                near_steps=NearSteps(robot, time_step)
                if predictor is not None and safety.mode == "safe"
                else 0,
                near_gap=safety.no_closer_gap,
                near_speed=safety.no_closer_speed,
            )
            nr = self.cbf.num_rows
            self.extra_constraints.append((self.cbf, np.zeros(nr), np.full(nr, np.inf)))
        # Effort J_eff = ½ Σ w_ν‖ν_k‖² (k=1..N) + w_u‖u_k‖² (k=0..N-1).
        self.effort_diagonal = np.zeros(L.num_variables)
        self.effort_diagonal[L.nu[1:].ravel()] = effort_weight_nu
        self.effort_diagonal[L.u.ravel()] = effort_weight_u
        # Penalty on the self-collision slacks: ½ w_q σ² + w_l σ.
        self.linear_cost = np.zeros(L.num_variables)
        self.effort_diagonal[self.self_collision.slack.ravel()] = SLACK_QUADRATIC_WEIGHT
        self.linear_cost[self.self_collision.slack.ravel()] = SLACK_LINEAR_WEIGHT
        # Variable bounds (eq. htmpc_limits); q_0, ν_0 pinned each step.
        lower = np.full(L.num_variables, -np.inf)
        upper = np.full(L.num_variables, np.inf)
        lower[L.q] = robot.q_lower
        upper[L.q] = robot.q_upper
        lower[L.nu] = robot.nu_lower
        upper[L.nu] = robot.nu_upper
        lower[L.u] = robot.nudot_lower
        upper[L.u] = robot.nudot_upper
        lower[self.self_collision.slack.ravel()] = 0.0
        if self.cbf is not None:
            self.effort_diagonal[self.cbf.slack] = SLACK_QUADRATIC_WEIGHT
            self.linear_cost[self.cbf.slack] = safety.human_slack_weight
            walls = self.cbf.slack[self.cbf.obstacle_rows]
            self.linear_cost[walls] = safety.obstacle_slack_weight
            near = self.cbf.slack[self.cbf.near_rows]
            self.linear_cost[near] = safety.no_closer_slack_weight
            lower[self.cbf.slack] = 0.0
        self.variable_lower = lower
        self.variable_upper = upper
        # SafetyConfig.turn_monitoring, `safe` only (control/separation.py).
        safety = safety or SafetyConfig()
        self.turn_monitoring = (
            safety if safety.turn_monitoring and safety.mode == "safe" else None
        )
        self._turn_bounds = None  # (the state's bytes, TurnBounds of it)
        # SafetyConfig.still_slack_weight, `safe` only (_WeighStillPeople).
        self.still_slack = (
            safety
            if self.cbf is not None
            and predictor is not None
            and safety.still_slack_weight > 0
            and safety.mode == "safe"
            else None
        )
        # Joint bounds that follow full braking where a joint cannot stop
        # before its limit (see WidenForBraking); False only to show that
        # the QP is infeasible without them.
        self.braking_consistent_bounds = True

    def ProximalMask(self, multipliers: bool) -> np.ndarray:
        """1 for every variable the RTI's proximal term damps, 0 for the
        predictor's multipliers unless ``multipliers`` (ControllerConfig.
        rti_proximal_multipliers)."""
        mask = np.ones(self.layout.num_variables)
        if not multipliers and self.predictor is not None:
            mask[self.predictor.MultiplierVariables()] = 0.0
        return mask

    def PatternKey(self) -> bytes:
        """Identifies the groups' current Jacobian sparsity patterns (they
        change only with the predictor's neighbour sets)."""
        return getattr(self.predictor, "pattern_key", b"")

    def VariableBounds(self, q0: np.ndarray, nu0: np.ndarray, turn: bool = True):
        """Variable bounds with the initial condition (eq. htmpc_init) pinned;
        with ``turn`` False, without the turn monitoring's bounds."""
        L = self.layout
        lower = self.variable_lower.copy()
        upper = self.variable_upper.copy()
        lower[L.q[0]] = upper[L.q[0]] = q0
        # The measured ν may sit marginally outside its limits; pinning it is
        # still consistent because only ν_1.. are bounded by the limits.
        lower[L.nu[0]] = upper[L.nu[0]] = nu0
        braking = BrakingTrajectory(self.robot, q0, nu0, self.time_step, L.N)
        if self.braking_consistent_bounds:
            WidenForBraking(L, braking, lower, upper)
        if self.joint_peaks is not None:
            self.joint_peaks.SetBraking(braking)
        if self.predictor is not None:
            self.predictor.ApplyBounds(lower, upper)
            if self.cbf is not None and self.cbf.num_guard:
                self.cbf.SetGuard(
                    self.predictor.p0,
                    self.predictor.v0,
                    self.time_step,
                    guarded=self.predictor.guarded,
                    active=self.predictor.active,
                )
            if self.cbf is not None and self.cbf.num_extra:
                self.cbf.SetExtra(
                    self.predictor.extra_p0,
                    self.predictor.extra_v0,
                    self.time_step,
                    self.predictor.extra_active,
                )
            if self.turn_monitoring is not None and turn:
                self._LimitTurn(lower, upper, q0, nu0)
            if self.still_slack is not None:
                self._WeighStillPeople(q0)
        return lower, upper

    def _WeighStillPeople(self, q0):
        """SafetyConfig.still_slack_weight: each slot's barrier slacks weigh
        human_slack_weight if the person walks toward the base faster than
        approach_speed (measured), still_slack_weight otherwise (a pure
        function of the measured state, set before each solve)."""
        safety, predictor = self.still_slack, self.predictor
        to_base = np.asarray(q0[:2], dtype=float) - predictor.p0
        distance = np.maximum(np.linalg.norm(to_base, axis=1), 1e-9)
        toward = np.einsum("hi,hi->h", predictor.v0, to_base) / distance
        weight = np.where(
            toward > safety.approach_speed,
            safety.human_slack_weight,
            safety.still_slack_weight,
        )
        slack = self.cbf.slack[self.cbf.person_rows]
        self.linear_cost[slack] = np.broadcast_to(weight[:, None], slack.shape)

    def TurnBounds(self, q0, nu0):
        """The yaw rate's bounds of SafetyConfig.turn_monitoring at the
        measured state (control/separation.py): (lower, upper), each (N+1, m)
        over every ν_k (the velocity limits elsewhere), or None where it is
        off or nothing binds."""
        predictor, safety = self.predictor, self.turn_monitoring
        if safety is None or predictor is None:
            return None
        people = np.concatenate(
            [
                predictor.p0[predictor.active],
                predictor.extra_p0[predictor.extra_active],
            ]
        )
        # A step asks twice (the warm start, then the stage QPs' bounds) for
        # the same state: the answer, a pure function of it, is kept once.
        key = b"".join(np.asarray(a, dtype=float).tobytes() for a in (q0, nu0, people))
        if self._turn_bounds is not None and self._turn_bounds[0] == key:
            return self._turn_bounds[1]
        bounds = self._TurnBounds(q0, nu0, people)
        self._turn_bounds = (key, bounds)
        return bounds

    def _TurnBounds(self, q0, nu0, people):
        """TurnBounds, computed (control/separation.py)."""
        safety = self.turn_monitoring
        limits = TurnLimits(
            self.robot,
            q0,
            nu0,
            people,
            human_radius=safety.human_radius,
            human_margin=safety.human_margin,
            floor=safety.turn_speed_floor,
            time_step=self.time_step,
            horizon=self.layout.N,
        )
        if limits is None:
            return None
        w, low, high = limits
        shape = (self.layout.N + 1, self.robot.num_velocities)
        lower = np.broadcast_to(self.robot.nu_lower, shape).copy()
        upper = np.broadcast_to(self.robot.nu_upper, shape).copy()
        lower[1 : 1 + low.size, w] = np.maximum(lower[1 : 1 + low.size, w], low)
        upper[1 : 1 + high.size, w] = np.minimum(upper[1 : 1 + high.size, w], high)
        return lower, upper

    def _LimitTurn(self, lower, upper, q0, nu0) -> None:
        """Bounds the base's yaw rate near people (TurnBounds)."""
        bounds = self.TurnBounds(q0, nu0)
        if bounds is None:
            return
        cols = np.asarray(self.layout.nu)[1:]
        lower[cols] = np.maximum(lower[cols], bounds[0][1:])
        upper[cols] = np.minimum(upper[cols], bounds[1][1:])

    @PROFILER.Timed("kinematics")
    def MakePoint(self, z: np.ndarray, targets: dict) -> LinearizationPoint:
        q, nu, u = self.layout.Split(z)
        return LinearizationPoint(
            z=z, q=q, nu=nu, u=u, kin=self.robot.CalcKinematics(q), targets=targets
        )

    def SafetyViolation(self, point: LinearizationPoint) -> float:
        """How far the plan at ``point`` violates the nonlinear barrier and
        self-collision rows (their QPs kept only the linearizations): the
        largest shortfall below a row's lower bound, 0 if none."""
        worst = 0.0
        for group, lower, _ in self.ConstraintGroups():
            if group is self.self_collision or group is self.cbf:
                g, _ = group.Eval(point)
                if g.size:
                    worst = max(worst, float(np.max(lower - g)))
        return worst

    def Rollout(
        self, q0: np.ndarray, nu0: np.ndarray, u: np.ndarray, nu_bounds=None
    ) -> np.ndarray:
        """z from integrating the model with inputs u (ν clipped to limits,
        or to ``nu_bounds``: (lower, upper), each (N+1, m))."""
        L = self.layout
        z = np.zeros(L.num_variables)
        z[L.q], z[L.nu], z[L.u] = Rollout(
            self.robot, q0, nu0, u, self.time_step, nu_bounds
        )
        return z

    def WarmStart(self, q0, nu0, inputs: np.ndarray) -> np.ndarray:
        """The guess z a step starts from: the inputs (N, m) rolled out from
        the measured state within TurnBounds (outside them the stage QPs
        were infeasible), with the predictor's humans along it.

        The HumanPredictor simulated the people along the unbounded rollout.
        Where the bounds change the robot's, the people are simulated again
        along it (Predictor.Restore): linearized at the people's responses
        to another robot plan, the KKT rows made the stage QPs primal
        infeasible (doorway, Stretch 3: 41 steps in 30 runs)."""
        z = self.Rollout(q0, nu0, inputs)
        bounds = self.TurnBounds(q0, nu0)
        # The bounds lie within the velocity limits: a rollout that keeps
        # within them is the bounded rollout too (no clip is ever active).
        nu = z[self.layout.nu][1:]
        bounded = bounds is not None and (
            np.any(nu < bounds[0][1:]) or np.any(nu > bounds[1][1:])
        )
        if bounded:
            z = self.Rollout(q0, nu0, inputs, bounds)
        if self.predictor is not None:
            self.predictor.WarmStart(z)
            if bounded:
                self.predictor.Restore(z)
        return z

    def ConstraintGroups(self) -> list[tuple[ConstraintGroup, np.ndarray, np.ndarray]]:
        """The (group, lower, upper) rows every stage shares."""
        out = [
            (
                self.dynamics,
                np.zeros(self.dynamics.num_rows),
                np.zeros(self.dynamics.num_rows),
            ),
        ]
        if self.self_collision.num_rows:
            nr = self.self_collision.num_rows
            out.append(
                (
                    self.self_collision,
                    np.full(nr, self.self_collision_distance),
                    np.full(nr, np.inf),
                )
            )
        if self.joint_peaks is not None and self.joint_peaks.num_rows:
            peaks = self.joint_peaks
            out.append((peaks, peaks.lower, peaks.upper))
        return out + list(self.extra_constraints)
