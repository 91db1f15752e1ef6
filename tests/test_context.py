"""Everything that lasts between control steps lives in the Context: a
cloned Context reproduces the run, and one Diagram (one HierarchicalMpc and
HumanPredictor instance) serves several Contexts at once."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from sm2ith_drake.diagrams.simulation import MakeSimulation
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.scenario_loader import LoadScenario


def _Diagram(name="crossing_ridgeback_ur10_3h", scenario_text="{}"):
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        scenario_name=name,
        scenario_text=scenario_text,
    )
    return MakeSimulation(scenario=scenario)


def _Log(diagram, context):
    logger = diagram.GetSubsystemByName("logger")
    return logger.GetLog(logger.GetMyContextFromRoot(context))


def _Commands(diagram, context):
    """The log's robot states and every control step's outcome (what the
    controller commanded, not how long it took)."""
    log = _Log(diagram, context)
    steps = [(r.time, r.mode, r.iterations, r.passes, r.status) for r in log.records]
    return np.array(log.states), steps


def _Advance(simulator, t):
    simulator.AdvanceTo(t)
    simulator.AdvancePendingEvents()


def _AssertSameRun(diagram, a, b):
    states_a, steps_a = _Commands(diagram, a)
    states_b, steps_b = _Commands(diagram, b)
    assert steps_a == steps_b
    np.testing.assert_array_equal(states_a, states_b)
    controller = diagram.GetSubsystemByName("controller")
    for port in ("command",):
        out = controller.GetOutputPort(port)
        np.testing.assert_array_equal(
            out.Eval(controller.GetMyContextFromRoot(a)),
            out.Eval(controller.GetMyContextFromRoot(b)),
        )


def test_a_cloned_context_reproduces_the_run():
    """5 s of a crossing with three people, then the Context is cloned and
    the original and the clone (in a second Simulator) both run 5 s more:
    identical commands and states (slots, neighbour sets, filtered
    preferred velocities and warm starts are all in the Context)."""
    diagram = _Diagram()
    first = Simulator(diagram)
    first.AdvanceTo(5.0)
    clone = first.get_context().Clone()
    second = Simulator(diagram, clone)
    _Advance(first, 10.0)
    _Advance(second, 10.0)
    _AssertSameRun(diagram, first.get_context(), second.get_context())
    log = _Log(diagram, first.get_context())
    assert log.times[-1] == 10.0 and len(log.records) >= 45
    assert all(r.mode == "solved" for r in log.records)


@pytest.mark.parametrize("reciprocity", [False, True])
def test_one_diagram_serves_two_contexts_interleaved(reciprocity):
    """Two runs from different robot starts, stepped alternately through the
    same systems, each match the same run done alone; also with the people's
    shares of the avoidance estimated online (evidence in the Context, the
    shares handed to the controller's KKT model with every prediction)."""
    enabled = "true" if reciprocity else "false"
    diagram = _Diagram(
        scenario_text=f"{{prediction: {{reciprocity: {{enabled: {enabled}}}}}}}"
    )
    robot = diagram.GetSubsystemByName("robot")
    contexts = []
    for dy in (0.0, 0.4):
        context = diagram.CreateDefaultContext()
        robot_context = robot.GetMyMutableContextFromRoot(context)
        x = robot_context.get_discrete_state_vector().CopyToVector()
        x[1] += dy
        robot_context.SetDiscreteState(x)
        contexts.append(context)
    solo = []
    for context in contexts:
        simulator = Simulator(diagram, context.Clone())
        _Advance(simulator, 3.0)
        solo.append(simulator)
    together = [Simulator(diagram, context.Clone()) for context in contexts]
    for t in np.arange(0.2, 3.0 + 1e-9, 0.2):
        for simulator in together:
            simulator.AdvanceTo(t)
    for simulator in together:
        simulator.AdvancePendingEvents()
    for alone, mixed in zip(solo, together, strict=True):
        _AssertSameRun(diagram, alone.get_context(), mixed.get_context())
    # The two runs are different runs.
    a, _ = _Commands(diagram, solo[0].get_context())
    b, _ = _Commands(diagram, solo[1].get_context())
    assert not np.array_equal(a, b)
    if reciprocity:
        predictor = diagram.GetSubsystemByName("human_predictor")
        shares = [
            predictor.GetPredictorState(
                predictor.GetMyContextFromRoot(s.get_context())
            ).last_prediction.robot_shares
            for s in solo
        ]
        # The estimates moved off the prior, differently in the two runs.
        assert np.any(np.abs(shares[0] - 0.5) > 0.01)
        assert not np.allclose(shares[0], shares[1])


def test_the_diagram_chains_estimator_predictor_controller():
    """HumanEstimator → HumanPredictor → HierarchicalMpc, and the plan
    back to the predictor (state-only, so no algebraic loop), as the
    --graphviz picture shows."""
    diagram = _Diagram("crossing_stretch3_2h")
    sources = {
        (dst.get_name(), int(dst_port)): src.get_name()
        for (dst, dst_port), (src, _) in diagram.connection_map().items()
    }
    estimator = diagram.GetSubsystemByName("human_estimator")
    predictor = diagram.GetSubsystemByName("human_predictor")
    controller = diagram.GetSubsystemByName("controller")

    def source(system, port):
        index = int(system.GetInputPort(port).get_index())
        return sources[(system.get_name(), index)]

    assert source(predictor, "human_estimate") == estimator.get_name()
    assert source(controller, "human_prediction") == predictor.get_name()
    assert source(predictor, "plan") == controller.get_name()
    dot = diagram.GetGraphvizString(max_depth=1)
    for name in ("human_estimator", "human_predictor", "controller"):
        assert f"name={name}" in dot


# A person who crosses when the robot enters the phase "go": the robot holds
# its start for 1 s (phase "wait"), then drives.
PHASE_TRIGGERED = """{
  sequence: [
    {name: wait, targets: {base_position: [0.0, 0.0]}, done_when: [base_position],
     tolerance: 0.5, hold_time: 1.0},
    {name: go, targets: {base_position: [2.0, 0.0]}, done_when: [base_position]}],
  humans: [{behavior: scripted, start: [1.0, 4.0], waypoints: [[1.0, -4.0]],
            speed: 1.0, start_phase: go, start_time: 0.5}],
  perception: {estimator: truth}}"""


def test_a_cloned_context_reproduces_a_phase_triggered_crossing():
    """The crowd learns the robot's phase from the planner; when the phase
    was entered lives in the crowd's Context, so a clone taken before it
    replays the same start. The person stands until the planner enters
    "go" (its own record of when), then walks start_time later."""
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name="stretch3_reach",
        scenario_text=PHASE_TRIGGERED,
    )
    diagram = MakeSimulation(scenario=scenario)
    first = Simulator(diagram)
    first.AdvanceTo(0.5)
    clone = first.get_context().Clone()
    second = Simulator(diagram, clone)
    _Advance(first, 2.5)
    _Advance(second, 2.5)
    _AssertSameRun(diagram, first.get_context(), second.get_context())
    crowd = diagram.GetSubsystemByName("crowd")
    planner = diagram.GetSubsystemByName("planner")
    states = [
        crowd.GetMyContextFromRoot(s.get_context()).get_abstract_state(0).get_value()
        for s in (first, second)
    ]
    np.testing.assert_array_equal(states[0].positions, states[1].positions)
    np.testing.assert_array_equal(states[0].phase_entered, states[1].phase_entered)
    entered = planner.GetSequenceState(
        planner.GetMyContextFromRoot(first.get_context())
    ).completed_at[0]  # "wait" completed: "go" entered
    # The crowd notices the phase at its next step (0.05 s).
    assert entered < states[0].phase_entered[0] <= entered + 0.05 + 1e-9
    walked = 4.0 - states[0].positions[0, 1]
    assert 2.5 - (entered + 0.5) - 0.1 <= walked <= 2.5 - (entered + 0.5) + 1e-9
    np.testing.assert_allclose(states[0].positions[0, 0], 1.0)
