"""One control step: warm start, hierarchical solve, and the safe fallback.

A solve that fails or overruns its wall-clock budget never leaves the robot
without a command: the previous plan, shifted, is replayed while it remains
consistent with the measured state (for at most ``max_fallback_steps``
steps); otherwise the robot brakes as hard as its acceleration limits allow.
Every fallback is counted.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from sm2ith_drake.control.backup import BackupFilter, BrakingAcceleration
from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.control.hierarchy import HierarchicalSolver, MpcSolution
from sm2ith_drake.control.prediction.factory import MakePredictor
from sm2ith_drake.control.prediction.orca_kkt import PredictionConsistency
from sm2ith_drake.control.prediction.predict import HumanPredictorModel
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.control.program import MpcProgram
from sm2ith_drake.control.recovery import Recovery, RecoveryState
from sm2ith_drake.control.robot_groups import ModelStep
from sm2ith_drake.control.tasks import MakeTask
from sm2ith_drake.humans.messages import HumanPrediction, MpcPlan
from sm2ith_drake.humans.robot_view import HumanDistances
from sm2ith_drake.scenario import (
    SOLVER_SETTINGS,
    ControllerConfig,
    ControlPeriod,
    SafetyConfig,
)

# A replayed plan is consistent while ν is this close to its ν (per entry).
_PLAN_CONSISTENCY_TOL = 0.05


@dataclass
class ControllerCounters:
    steps: int = 0
    solver_failures: int = 0
    overruns: int = 0
    fallbacks: int = 0
    shifted_plan_fallbacks: int = 0
    braking_fallbacks: int = 0
    # Shifted-plan replays refused because they would close in on a person
    # faster than the DT-CBF allows (the robot brakes instead).
    unsafe_replays: int = 0
    # Steps driven by the recovery instead of the MPC (ControllerConfig.recovery).
    recovery_steps: int = 0
    # Solved steps whose command the backup filter replaced by braking
    # (SafetyConfig.backup_filter).
    filtered_steps: int = 0


@dataclass
class StepRecord:
    """What happened in one control step (for metrics and the benchmark)."""

    time: float = 0.0
    wall_time: float = 0.0
    solve_time: float = 0.0
    iterations: int = 0
    passes: int = 0  # RTI passes run (see HierarchicalSolver.Solve)
    success: bool = True
    # "solved" | "filtered" | "shifted_plan" | "brake" | "recovery"
    mode: str = "none"
    status: str = ""
    # With ControllerConfig.check_predictions and the ORCA-KKT predictor:
    # ‖a_QP − a_predicted‖ of every active human and prediction step, from
    # re-solving each human's relaxed-ORCA QP at the planned states (m/s).
    prediction_errors: np.ndarray | None = None


@dataclass
class ControllerState:
    """The controller's persistent state (held in the Context)."""

    # The last plan that was solved successfully, and how many control steps
    # ago it was solved.
    plan: MpcSolution | None = None
    plan_age: int = 0
    # The most recent solve attempt (successful or not), for visualization
    # and diagnostics.
    last_solution: MpcSolution | None = None
    command_u: np.ndarray | None = None
    command_nu: np.ndarray | None = None
    counters: ControllerCounters = field(default_factory=ControllerCounters)
    record: StepRecord = field(default_factory=StepRecord)
    recovery: RecoveryState = field(default_factory=RecoveryState)


def WarmStartInputs(plan, plan_age: int, shift: int, horizon: int, num_velocities: int):
    """The inputs (N, m) a control step starts from: the last successful
    plan's, shifted by the control steps since it was solved (``plan_age``
    + 1 periods of ``shift`` MPC steps each), zeros beyond it or without one."""
    u = np.zeros((horizon, num_velocities))
    if plan is not None:
        previous = plan.u[shift * (plan_age + 1) :]
        u[: len(previous)] = previous
    return u


class MpcController:
    """The plain-Python controller behind the HierarchicalMpc LeafSystem.

    Attributes:
        program: the MpcProgram every stage shares.
        solver: the HierarchicalSolver; any object with its ``Solve(*, q0,
            nu0, targets, z_guess)`` may replace it (a declared seam: tests
            use it to make a solve fail and exercise the fallback).
        predictor: the prediction model embedded in the program, or None.
        human_predictor: the HumanPredictorModel of the same configuration
            (for callers that step the controller without the HumanPredictor
            system), or None.
    """

    @classmethod
    def FromScenario(cls, robot, scenario) -> MpcController:
        """The controller a Scenario describes (its tasks, controller,
        prediction, safety and obstacles) for ``robot``."""
        return cls(
            robot,
            scenario.tasks,
            scenario.controller,
            prediction=scenario.prediction,
            safety=scenario.safety,
            obstacles=scenario.obstacles,
        )

    def __init__(
        self,
        robot,
        tasks,
        config: ControllerConfig,
        *,
        prediction=None,
        safety=None,
        obstacles=(),
    ):
        """``prediction`` (a PredictionConfig) adds ``max_humans`` human slots
        with its predictor and the DT-CBF constraints of ``safety``;
        ``obstacles`` (ObstacleConfigs) add static DT-CBF constraints."""

        self.robot = robot
        self.config = config
        self.tasks = [
            t if not hasattr(t, "kind") else MakeTask(t, robot.num_positions)
            for t in tasks
        ]
        names = [t.name for t in self.tasks]
        if len(set(names)) != len(names):
            raise ValueError(f"task names must be unique: {names}")
        segments = ObstacleSegments(obstacles)
        self.predictor = None
        self.human_predictor = None
        if prediction is not None:
            # The predictor's math, for callers without a HumanPredictor
            # system (tests, scripts) and for the empty prediction.
            self.human_predictor = HumanPredictorModel(
                prediction,
                horizon=config.horizon,
                time_step=config.time_step,
                control_period=ControlPeriod(config),
                robot=robot,
                obstacles=segments,
                human_radius=(safety or SafetyConfig()).human_radius,
            )
            self.predictor = MakePredictor(
                prediction,
                horizon=config.horizon,
                time_step=config.time_step,
                robot=robot,
                obstacles=segments,
                human_radius=(safety or SafetyConfig()).human_radius,
            )
        self.program = MpcProgram(
            robot=robot,
            tasks=self.tasks,
            horizon=config.horizon,
            time_step=config.time_step,
            self_collision_distance=config.self_collision_distance,
            effort_weight_nu=config.effort_weight_nu,
            effort_weight_u=config.effort_weight_u,
            predictor=self.predictor,
            safety=safety,
            obstacle_segments=segments,
            joint_limits_between_knots=config.joint_limits_between_knots,
        )
        self.solver = HierarchicalSolver(
            self.program,
            method=config.method,
            solver=config.solver,
            solver_options=config.solver_options,
            lexicographic_tolerance=config.lexicographic_tolerance,
            rti_iterations=config.rti_iterations,
            rti_proximal_weight=config.rti_proximal_weight
            * self.program.ProximalMask(config.rti_proximal_multipliers),
            **{name: getattr(config, name) for name in SOLVER_SETTINGS},
        )
        self.safety = safety or SafetyConfig()
        self.period = ControlPeriod(config)
        self.shift = max(1, int(round(self.period / config.time_step)))
        self.backup_filter = None
        if self.safety.mode == "safe" and self.safety.backup_filter:
            self.backup_filter = BackupFilter(
                robot,
                period=self.period,
                human_radius=self.safety.human_radius,
                margin=self.safety.backup_margin,
                walls=segments,
                wall_margin=0.5 * self.safety.obstacle_margin,
                # React predicts nothing: people held where measured.
                people_move=self.predictor is None or self.predictor.name != "react",
            )
        self.recovery = Recovery(
            robot,
            self.tasks,
            config.recovery,
            walls=segments,
            safety=self.safety,
            period=self.period,
        )

    def EmptyPrediction(self) -> HumanPrediction:
        """The prediction with nobody tracked."""
        model = self.human_predictor
        prediction = model.Predict(model.InitialState(), estimate=None)[0]
        prediction.compute_time = 0.0  # made inside the step it is used in
        return prediction

    @PROFILER.Timed("warm_start")
    def WarmStart(self, state: ControllerState, q0, nu0) -> np.ndarray:
        """The previous plan's inputs shifted by one period, rolled out from
        the measured state, with the humans along it (MpcProgram.WarmStart)."""
        return self.program.WarmStart(q0, nu0, self.WarmStartInputs(state))

    def WarmStartInputs(self, state: ControllerState) -> np.ndarray:
        """The robot inputs the next step starts from (WarmStartInputs)."""
        N, m = self.program.layout.N, self.robot.num_velocities
        return WarmStartInputs(state.plan, state.plan_age, self.shift, N, m)

    def Plan(self, state: ControllerState) -> MpcPlan:
        """The ``plan`` output of a state: its latest solution and the inputs
        the next step will start from."""
        return MpcPlan(
            solution=state.last_solution,
            warm_start_inputs=self.WarmStartInputs(state),
        )

    @PROFILER.Timed("control_step")
    def Step(
        self,
        state: ControllerState,
        *,
        time_now: float,
        q0,
        nu0,
        targets: dict,
        prediction: HumanPrediction | None = None,
        done_tolerances: dict | None = None,
    ) -> ControllerState:
        """Computes the next command; returns the new state (input unchanged).

        ``prediction`` is the HumanPredictor's output for this step (ignored
        without a predictor; None: nobody tracked). The prediction's own
        compute time counts as part of the step (record and time budget).
        ``done_tolerances``: TaskReferences.done_tolerances (the recovery's)."""
        start = time.perf_counter()
        q0 = np.asarray(q0, dtype=float)
        nu0 = np.asarray(nu0, dtype=float)
        new = copy.copy(state)
        new.counters = copy.copy(state.counters)
        new.counters.steps += 1
        record = StepRecord(time=time_now)
        solution = None
        humans = None
        if self.predictor is not None:
            prediction = prediction or self.EmptyPrediction()
            self.predictor.SetPrediction(prediction)
            humans = prediction.estimate
            start -= prediction.compute_time
        u = self._Recover(
            new, state, time_now, q0, nu0, targets, humans, done_tolerances
        )
        if u is not None:
            record.mode = record.status = "recovery"
            new.plan, new.plan_age, new.last_solution = None, 0, None
            new.counters.recovery_steps += 1
            return self._Command(new, record, u, nu0, start)
        if np.all(np.isfinite(q0)) and np.all(np.isfinite(nu0)):
            try:
                solution = self.solver.Solve(
                    q0=q0,
                    nu0=nu0,
                    targets=targets,
                    z_guess=self.WarmStart(state, q0, nu0),
                )
            except (RuntimeError, ValueError, np.linalg.LinAlgError) as e:
                record.status = f"solver error: {e}"
        else:
            record.status = "non-finite robot state"
        elapsed = time.perf_counter() - start
        ok = solution is not None and solution.success
        if solution is not None:
            record.solve_time = solution.solve_time
            record.iterations = solution.iterations
            record.passes = solution.passes
            record.status = solution.status
            new.last_solution = solution
        if not ok:
            new.counters.solver_failures += 1
        elif self.config.time_budget > 0 and elapsed > self.config.time_budget:
            ok = False
            new.counters.overruns += 1
            record.status = f"overrun ({elapsed * 1e3:.0f} ms)"
        if ok:
            new.plan, new.plan_age = solution, 0
            u = solution.u[0]
            record.mode = "solved"
            if self.backup_filter is not None and not self.backup_filter.Admits(
                q0, nu0, u, humans
            ):
                u = BrakingAcceleration(self.robot, nu0, self.period)
                new.counters.filtered_steps += 1
                record.mode = "filtered"
        else:
            new.counters.fallbacks += 1
            u = self.ReplayPlan(state, nu0)
            if u is not None and not self.ReplayIsSafe(q0, nu0, u, humans):
                u = None
                new.counters.unsafe_replays += 1
            if u is not None:
                new.plan_age = state.plan_age + 1
                new.counters.shifted_plan_fallbacks += 1
                record.mode = "shifted_plan"
            else:
                safe_nu = np.nan_to_num(nu0)
                u = BrakingAcceleration(self.robot, safe_nu, self.period)
                new.plan = None
                new.counters.braking_fallbacks += 1
                record.mode = "brake"
        record.success = ok
        new = self._Command(new, record, u, nu0, start)
        if (
            ok
            and self.config.check_predictions
            and self.predictor is not None
            and self.predictor.name == "orca_kkt"
        ):
            record.prediction_errors = PredictionConsistency(
                self.predictor, solution.z, self.program.layout
            ).ravel()
        return new

    def _Command(self, new: ControllerState, record, u, nu0, start) -> ControllerState:
        """Finishes a step: the command from the input u, and the record."""
        new.command_u = np.asarray(u, dtype=float)
        new.command_nu = np.clip(
            np.nan_to_num(nu0) + self.period * new.command_u,
            self.robot.nu_lower,
            self.robot.nu_upper,
        )
        record.wall_time = time.perf_counter() - start
        new.record = record
        return new

    def _Recover(self, new, state, time_now, q0, nu0, targets, humans, tolerances):
        """The input u of a step that the recovery drives (its state updated
        in ``new``), or None for the MPC to plan. The base velocity it asks
        for is reached as fast as the acceleration limits allow, the arm
        held; a step that would close in on a person or a wall faster than
        the DT-CBF allows ends the recovery instead."""
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(nu0))):
            return None
        new.recovery, nu_base = self.recovery.Step(
            state.recovery,
            time_now=time_now,
            q0=q0,
            targets=targets,
            humans=humans,
            done_tolerances=tolerances,
        )
        if nu_base is None:
            return None
        nu_want = np.zeros(self.robot.num_velocities)
        nu_want[: len(nu_base)] = nu_base
        lower, upper = self.robot.nudot_lower, self.robot.nudot_upper
        u = np.clip((nu_want - nu0) / self.period, lower, upper)
        q1, _ = ModelStep(self.robot, q0, nu0, u, self.period)
        # The walls: the DT-CBF holds, or the step keeps at least half the
        # obstacle margin (a route may run within the margin: it was planned
        # in a distance field that errs by a few cm, toward caution).
        h0, h1 = self.recovery.WallBarrier(q0), self.recovery.WallBarrier(q1)
        floor = -0.5 * self.safety.obstacle_margin
        walls_ok = h1 >= min((1.0 - self.safety.gamma) * h0, floor)
        if walls_ok and self.ReplayIsSafe(q0, nu0, u, humans):
            return u
        end = "recovery ended: the barriers refused a step"
        new.recovery = dataclasses.replace(new.recovery, route=None, status=end)
        return None

    def ReplayIsSafe(self, q0, nu0, u, humans) -> bool:
        """Whether replaying ``u`` for one control period keeps the DT-CBF
        h(x₁) ≥ (1 − γ) h(x₀) against every tracked human moving on at its
        measured velocity (the first-step guard the solved plans obey). A
        stale plan was made for where people were, not where they are."""
        if self.predictor is None or humans is None or not len(humans.positions):
            return True
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(nu0))):
            return False
        dt = self.period
        q1, _ = ModelStep(self.robot, q0, nu0, u, dt)
        p0 = np.asarray(humans.positions, dtype=float)
        p1 = p0 + dt * np.nan_to_num(np.asarray(humans.velocities, dtype=float))
        reach = self.safety.human_radius + self.safety.human_margin
        h0 = HumanDistances(self.robot, q0[None], p0[None])[0] - reach
        h1 = HumanDistances(self.robot, q1[None], p1[None])[0] - reach
        return bool(np.all(h1 >= (1.0 - self.safety.gamma) * h0 - 1e-9))

    def ReplayPlan(self, state: ControllerState, nu0):
        plan = state.plan
        if plan is None:
            return None
        age = state.plan_age + 1
        j = self.shift * age
        if age > self.config.max_fallback_steps or j >= len(plan.u):
            return None
        if not np.all(np.isfinite(nu0)):
            return None
        if np.max(np.abs(plan.nu[j] - nu0)) > _PLAN_CONSISTENCY_TOL:
            return None
        return plan.u[j]

    def InitialState(self) -> ControllerState:
        m = self.robot.num_velocities
        return ControllerState(command_u=np.zeros(m), command_nu=np.zeros(m))
