"""The benchmark behind ``sm2ith bench``: the robot's reach task among
scripted people, run closed loop, timed per control step.
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.errors import UserError
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
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
) -> dict:
    """Runs the benchmark closed loop; returns the per-step timing figures."""

    scenario = BenchmarkScenario(
        robot, humans, predictor, solver, rti_iterations, scenario_text
    )
    # The logger sees a step at its next sample: run a little past step K
    # and keep the first K.
    duration = (steps + 0.5) * ControlPeriod(scenario.controller)
    result = RunSimulation(scenario, duration=duration)
    records = [r for r in result.log.records if r.mode != "none"][:steps]
    wall = np.array([r.wall_time for r in records]) * 1e3
    iters = np.array([r.iterations for r in records], dtype=float)
    return {
        "robot": robot,
        "humans": humans,
        "predictor": predictor if humans else "none",
        "solver": solver,
        "rti_iterations": scenario.controller.rti_iterations,
        "max_neighbors": scenario.prediction.max_neighbors,
        "scenario_text": scenario_text,
        "steps": len(records),
        "median_ms": float(np.median(wall)),
        "p95_ms": float(np.percentile(wall, 95)),
        "max_ms": float(wall.max()),
        # None when the solver does not report iterations (SNOPT, IPOPT).
        "mean_iterations": None if np.any(iters < 0) else float(iters.mean()),
        "mean_passes": float(np.mean([r.passes for r in records])),
        "solver_failures": int(
            sum(
                not r.status.startswith("solved") and not r.status.startswith("overrun")
                for r in records
            )
        ),
        "fallbacks": int(sum(r.mode != "solved" for r in records)),
    }
