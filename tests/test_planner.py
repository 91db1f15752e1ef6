"""Task sequences in the TaskPlanner (pick-and-place)."""

import numpy as np
import pytest

from sm2ith_drake.diagrams import RunSimulation
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.scenario import LoadScenario, ScenarioError

FILE = GetDiagramsDir() / "pick_and_place.scenarios.yaml"


def test_pick_and_place_runs_every_phase_in_order():
    scenario = LoadScenario(
        filename=FILE, scenario_name="pick_and_place_ridgeback_ur10"
    )
    result = RunSimulation(scenario)
    m = result.metrics
    assert m["phases_completed"] == 5
    assert m["sequence_time"] < scenario.simulation_duration
    assert m["solver_failures"] == 0 and m["limit_violations"] == 0
    # The robot really went to both locations and back: the base passed
    # within the phase tolerance of the pick and place locations.
    base = np.array(result.log.states)[:, :2]
    for goal in ([2.0, 1.5], [2.0, -1.5], [0.0, 0.0]):
        assert np.min(np.linalg.norm(base - goal, axis=1)) < 0.1
    # …in that order.
    first = [
        int(np.argmax(np.linalg.norm(base - g, axis=1) < 0.1))
        for g in ([2.0, 1.5], [2.0, -1.5])
    ]
    assert first[0] < first[1]


def test_sequence_with_an_unknown_task_is_rejected():
    text = "{sequence: [{name: x, targets: {ee_pose: [0, 0, 0]}}]}"
    with pytest.raises(ScenarioError, match="unknown tasks"):
        LoadScenario(
            filename=FILE,
            scenario_name="pick_and_place_ridgeback_ur10",
            scenario_text=text,
        )
