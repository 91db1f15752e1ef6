"""RunSimulation: build a scenario's simulation, run it, and summarize it."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorStatus
from pydrake.systems.framework import EventStatus
from tqdm import tqdm

from sm2ith_drake.diagrams.simulation import MakeSimulation
from sm2ith_drake.run.metrics import SummarizeRun
from sm2ith_drake.scenario import Scenario


@dataclasses.dataclass
class RunResult:
    log: object
    metrics: dict
    diagram: object
    html_path: str | None = None


def RunSimulation(
    scenario: Scenario,
    *,
    meshcat: Meshcat | None = None,
    duration: float | None = None,
    html_path: str | None = None,
    robot=None,
    tasks=None,
    progress: bool = False,
    realtime_rate: float | None = None,
    stop_when_done: bool = False,
) -> RunResult:
    """Builds and simulates ``scenario``; returns the log and its metrics.

    If ``html_path`` is given (and ``meshcat``), the run is recorded and saved
    as a self-contained HTML replay. ``realtime_rate`` overrides the
    scenario's simulator_config (1.0: real time; 0: as fast as possible).
    With ``stop_when_done`` a run with a task sequence ends as soon as its
    last phase is completed (the campaigns' navigation time); otherwise it
    runs for the scenario's duration.
    """
    diagram = MakeSimulation(
        scenario=scenario, meshcat=meshcat, robot=robot, tasks=tasks
    )
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    if realtime_rate is not None:
        simulator.set_target_realtime_rate(realtime_rate)
    if meshcat is not None and html_path:
        meshcat.StartRecording(set_visualizations_while_recording=True)
    end = scenario.simulation_duration if duration is None else duration
    if stop_when_done and scenario.sequence:
        planner = diagram.GetSubsystemByName("planner")
        num_phases = len(scenario.sequence)

        def monitor(root_context):
            seq = planner.GetSequenceState(planner.GetMyContextFromRoot(root_context))
            if len(seq.completed_at) >= num_phases:
                return EventStatus.ReachedTermination(planner, "sequence completed")
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
    simulator.Initialize()
    if progress:
        with tqdm(
            total=round(end, 1), unit="s", desc="simulated", file=sys.stderr
        ) as bar:
            for i in range(1, max(1, int(np.ceil(end))) + 1):
                status = simulator.AdvanceTo(min(end, i))
                bar.update(round(simulator.get_context().get_time() - bar.n, 1))
                if (
                    status.reason()
                    == SimulatorStatus.ReturnReason.kReachedTerminationCondition
                ):
                    break
    else:
        simulator.AdvanceTo(end)
    # AdvanceTo leaves the update events due at the final time for the next
    # call; perform them, so the logger records its sample at the end too.
    simulator.AdvancePendingEvents()
    context = simulator.get_context()
    logger = diagram.GetSubsystemByName("logger")
    log = logger.GetLog(logger.GetMyContextFromRoot(context))
    controller = diagram.GetSubsystemByName("controller")
    saved = None
    if meshcat is not None and html_path:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        Path(html_path).parent.mkdir(parents=True, exist_ok=True)
        Path(html_path).write_text(meshcat.StaticHtml())
        saved = str(html_path)
    metrics = SummarizeRun(
        log,
        controller.controller.robot,
        human_radii=[h.radius for h in scenario.humans] if scenario.humans else None,
    )
    if scenario.sequence:
        planner = diagram.GetSubsystemByName("planner")
        seq = planner.GetSequenceState(planner.GetMyContextFromRoot(context))
        metrics["phases_completed"] = len(seq.completed_at)
        if len(seq.completed_at) == len(scenario.sequence):
            metrics["sequence_time"] = float(seq.completed_at[-1])
    return RunResult(log=log, metrics=metrics, diagram=diagram, html_path=saved)
