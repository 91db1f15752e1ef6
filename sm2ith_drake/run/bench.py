"""The benchmark behind ``sm2ith bench``: the robot's reach task among
scripted people, run closed loop, timed per control step.

The simulation is advanced one control instant at a time: to the instant
(the robot and the people move; that instant's events stay pending), then
the instant's events are performed (the HumanPredictor's prediction, the
controller's step, the logger, ...). The second part is the *control
instant* timed here and, with ``profile=True``, one step of the phase
profiler (control/profiling.py). ``median_ms`` etc. are the controller's own
step (``StepRecord.wall_time``: MpcController.Step, which does not include
the HumanPredictor's prediction); ``instant_*`` the whole control instant.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

from sm2ith_drake.control.hierarchy import SolvedThrough
from sm2ith_drake.control.hpipm_library import StageQpSolver
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.diagrams.simulation import MakeSimulation
from sm2ith_drake.errors import UserError
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.realtime import FreezeHeap
from sm2ith_drake.run.walkers import ScriptedWalkers
from sm2ith_drake.scenario import ControlPeriod, ScenarioError
from sm2ith_drake.scenario_loader import ApplyScenarioText, LoadScenarioAndRobot


def BenchmarkScenario(
    robot: str,
    humans: int,
    predictor: str,
    solver: str = "rti",
    rti_iterations: int | None = None,
    scenario_text: str = "",
):
    """The benchmark scenario: the robot's reach task with ``humans``
    scripted people pacing across its way; ``scenario_text`` (YAML) is
    applied on top, e.g. "{prediction: {max_neighbors: 9}}"."""

    if humans < 0:
        raise UserError("--humans must be ≥ 0")
    text = f"{{controller: {{solver: {solver}}}}}"
    try:
        scenario, _ = LoadScenarioAndRobot(
            filename=GetDiagramsDir() / "benchmark.scenarios.yaml",
            scenario_name=f"bench_{robot}",
            scenario_text=text,
        )
    except ScenarioError as e:
        raise UserError(str(e)) from e
    # People pacing back and forth across the robot's way (scripted, so the
    # crowd is the same for every predictor), seen without perception noise.
    scenario.humans.extend(
        ScriptedWalkers(humans, x_start=0.8, x_span=2.4, half_width=2.5, base_speed=0.8)
    )
    scenario.prediction.predictor = predictor
    scenario.prediction.max_humans = max(humans, 1)
    scenario.perception.estimator = "truth"
    if humans and predictor == "orca_kkt":
        # As the shipped crowd scenarios: two SQP passes for the KKT model.
        scenario.controller.rti_iterations = 2
    if rti_iterations is not None:
        if rti_iterations < 1:
            raise UserError("--rti_iterations must be ≥ 1")
        scenario.controller.rti_iterations = rti_iterations
    try:
        return ApplyScenarioText(scenario, scenario_text)
    except ScenarioError as e:
        raise UserError(f"--scenario_text: {e}") from e


def RunBenchmark(
    *,
    robot: str,
    humans: int = 0,
    predictor: str = "orca_kkt",
    steps: int = 100,
    solver: str = "rti",
    rti_iterations: int | None = None,
    scenario_text: str = "",
    profile: bool = False,
) -> dict:
    """Runs the benchmark closed loop; returns the per-step timing figures.

    ``profile``: also time the phases of every control instant (the
    ``profile`` entry: median ms per phase, control/profiling.py)."""

    scenario = BenchmarkScenario(
        robot, humans, predictor, solver, rti_iterations, scenario_text
    )
    if steps < 1:
        raise UserError("--steps must be ≥ 1")
    was_enabled = PROFILER.enabled
    PROFILER.Reset()
    if profile:
        PROFILER.Enable()
    try:
        log, setup, instants = _Simulate(scenario, steps)
    finally:
        PROFILER.enabled = was_enabled
    # The logger sees a step at its next sample: its records of instants
    # 1 … K are the steps 0 … K−1.
    records = [r for r in log.records if r.mode != "none"][:steps]
    wall = np.array([r.wall_time for r in records]) * 1e3
    iters = np.array([r.iterations for r in records], dtype=float)
    return {
        "robot": robot,
        "humans": humans,
        "predictor": predictor if humans else "none",
        "solver": solver,
        # The stage QPs' solver (auto is PIQP alone without HPIPM).
        "qp_solver": StageQpSolver(scenario.controller.qp_solver),
        "rti_iterations": scenario.controller.rti_iterations,
        "max_neighbors": scenario.prediction.max_neighbors,
        "kkt_steps": scenario.prediction.kkt_steps,
        "scenario_text": scenario_text,
        "steps": len(records),
        "median_ms": float(np.median(wall)),
        "p95_ms": float(np.percentile(wall, 95)),
        "p99_ms": float(np.percentile(wall, 99)),
        "max_ms": float(wall.max()),
        "first_step_ms": float(wall[0]),
        "setup_ms": setup * 1e3,
        "instant_median_ms": float(np.median(instants)),
        "instant_p99_ms": float(np.percentile(instants, 99)),
        # None when the solver does not report iterations (SNOPT, IPOPT).
        "mean_iterations": None if np.any(iters < 0) else float(iters.mean()),
        "mean_passes": float(np.mean([r.passes for r in records])),
        "solver_failures": int(
            sum(
                not r.status.startswith("solved") and not r.status.startswith("overrun")
                for r in records
            )
        ),
        # A solved step whose command the backup filter replaced by braking
        # is not a fallback (it is counted apart).
        "fallbacks": int(sum(r.mode not in ("solved", "filtered") for r in records)),
        "filtered": int(sum(r.mode == "filtered" for r in records)),
        # Solved steps whose lower stages went unoptimized (a stage's QP
        # failed, or controller.qp_iteration_budget ran out).
        "solved_through": int(sum(SolvedThrough(r.status) for r in records)),
        **(_Profile(steps) if profile else {}),
    }


def _Simulate(scenario, steps: int):
    """Builds the simulation (timed: the setup), then runs control instants
    0 … ``steps`` one by one (module doc). Returns the log, the setup's wall
    time (s) and the first ``steps`` instants' wall times (ms)."""
    start = time.perf_counter()
    diagram = MakeSimulation(scenario=scenario)
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    simulator.Initialize()
    FreezeHeap()
    setup = time.perf_counter() - start
    period = ControlPeriod(scenario.controller)
    instants = []
    for k in range(steps + 1):
        if k:  # (AdvanceTo would perform the pending events of time 0)
            simulator.AdvanceTo(k * period)
        PROFILER.BeginStep()
        start = time.perf_counter()
        simulator.AdvancePendingEvents()
        instants.append(time.perf_counter() - start)
        PROFILER.EndStep()
    context = simulator.get_context()
    controller = diagram.GetSubsystemByName("controller")
    state = controller.GetControllerState(controller.GetMyContextFromRoot(context))
    if state.counters.steps != steps + 1:
        raise RuntimeError(
            f"the benchmark ran {state.counters.steps} control steps, "
            f"not one per instant ({steps + 1})"
        )
    logger = diagram.GetSubsystemByName("logger")
    log = logger.GetLog(logger.GetMyContextFromRoot(context))
    return log, setup, np.array(instants[:steps]) * 1e3


def _Profile(steps: int) -> dict:
    """The profiler's medians over the first ``steps`` control instants."""
    chosen = slice(0, steps)
    return {
        "profile": PROFILER.Summary(chosen),
        "profile_inclusive": PROFILER.InclusiveSummary(chosen),
        "profile_calls": PROFILER.CallsPerStep(chosen),
    }
