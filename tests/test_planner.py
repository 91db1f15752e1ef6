"""Task sequences in the TaskPlanner (pick-and-place)."""

import numpy as np
import pytest

from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario import ScenarioError
from sm2ith_drake.scenario_loader import LoadScenario

FILE = GetDiagramsDir() / "pick_and_place.scenarios.yaml"


@pytest.mark.parametrize(
    "name", ["pick_and_place_ridgeback_ur10", "pick_and_place_stretch3"]
)
def test_pick_and_place_runs_every_phase_in_order(name):
    scenario = LoadScenario(filename=FILE, scenario_name=name)
    result = RunSimulation(scenario)
    m = result.metrics
    assert m["phases_completed"] == len(scenario.sequence) == 5
    assert m["sequence_time"] < scenario.simulation_duration
    assert m["solver_failures"] == 0 and m["limit_violations"] == 0
    # The base really reached each location (within the phase tolerance),
    # in the order of the sequence.
    base = np.array(result.log.states)[:, :2]
    first = []
    for phase in scenario.sequence:
        if "base_position" in phase.targets and "base_position" in phase.done_when:
            near = np.linalg.norm(base - phase.targets["base_position"], axis=1)
            near = near < phase.tolerance + 1e-6
            start = first[-1] if first else 0
            assert np.any(near[start:]), phase.name
            first.append(start + int(np.argmax(near[start:])))
    assert len(first) == 3 and first == sorted(first)


def test_sequence_with_an_unknown_task_is_rejected():
    text = "{sequence: [{name: x, targets: {ee_pose: [0, 0, 0]}}]}"
    with pytest.raises(ScenarioError, match="unknown tasks"):
        LoadScenario(
            filename=FILE,
            scenario_name="pick_and_place_ridgeback_ur10",
            scenario_text=text,
        )


def test_bounded_run_log_keeps_the_latest_window():
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from sm2ith_drake.control.tasks import MakeTask
    from sm2ith_drake.diagrams.control_stack import AddControlStack
    from sm2ith_drake.scenario_loader import MakeRobot
    from sm2ith_drake.systems.robot import KinematicRobot

    scenario = LoadScenario(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name="stretch3_reach",
    )
    robot = MakeRobot(scenario)
    tasks = [MakeTask(t, robot.num_positions) for t in scenario.tasks]
    builder = DiagramBuilder()
    sim = builder.AddSystem(KinematicRobot(robot, initial_q=robot.default_q))
    stack = AddControlStack(builder, scenario, robot, tasks, max_log_samples=20)
    for port in stack.robot_state_inputs:
        builder.Connect(sim.GetOutputPort("state"), port)
    builder.Connect(stack.command, sim.GetInputPort("command"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(10.0)
    # The logger records in an update event: the one due at 10 s is pending.
    simulator.AdvancePendingEvents()
    logger = diagram.GetSubsystemByName("logger")
    log = logger.GetLog(logger.GetMyContextFromRoot(simulator.get_context()))
    total = log.dropped_samples + len(log.times)
    assert 15 <= len(log.times) <= 20 and total >= 49
    assert log.times[-1] == pytest.approx(10.0)
    assert all(len(e) == len(log.times) for e in log.task_errors.values())
    assert len(log.records) + log.dropped_records == log.counters.steps
    assert log.records[0].time >= log.times[0] - 1e-9
    assert len(log.stage_errors) == len(log.records)
