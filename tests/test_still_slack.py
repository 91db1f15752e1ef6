"""safety.still_slack_weight: the barrier slacks of a person not walking
toward the robot weigh still_slack_weight, those of one walking toward it
human_slack_weight, in the `safe` variant; in a squeeze between a person
standing and one walking into the robot, the plan gives up the walking
person's margin rather than the standing one's."""

import dataclasses

import numpy as np
import pytest
from first_prediction import FirstStep

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.humans.robot_view import HumanDistances
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.scenario import ScenarioError
from sm2ith_drake.scenario_checks import ValidateScenario
from sm2ith_drake.scenario_loader import LoadScenario, MakeRobot

CROSSING = GetDiagramsDir() / "crossing.scenarios.yaml"


def _Controller(name="crossing_stretch3_2h", **safety):
    scenario = LoadScenario(filename=CROSSING, scenario_name=name)
    robot = MakeRobot(scenario)
    controller = MpcController(
        robot,
        scenario.tasks,
        scenario.controller,
        prediction=scenario.prediction,
        safety=dataclasses.replace(scenario.safety, **safety),
    )
    return scenario, robot, controller


def _PersonAt(robot, q0, direction, gap, radius):
    """A point along ``direction`` from the base whose surface gap to the
    robot is ``gap``."""
    direction = np.asarray(direction, dtype=float)
    p = q0[:2] + 3.0 * direction
    while HumanDistances(robot, q0[None], p[None, None])[0, 0] - radius > gap:
        p -= 0.002 * direction
    return p


def test_person_rows_are_the_rows_of_their_slot():
    """Moving one slot's person (their predicted positions and the guards'
    measured one) changes exactly the rows ``person_rows`` names for that
    slot: the horizon's and the moving and static guards'."""
    _, robot, controller = _Controller(guard_steps=3, static_guard_steps=2)
    program = controller.program
    cbf, L = program.cbf, program.layout
    z = np.zeros(L.num_variables)
    z[L.q] = np.array(robot.default_q, dtype=float)
    H = cbf.static_p0.shape[0]
    people = np.array([[1.0 + j, 0.5 * j] for j in range(H)])
    v = np.full((H, 2), 0.2)

    def Rows(p):
        z[cbf._P] = p[None]
        cbf.SetGuard(p, v, 0.2)
        return cbf.Eval(program.MakePoint(z, {}))[0]

    base = Rows(people)
    assert cbf.person_rows.shape[0] == H
    for j in range(H):
        moved = people.copy()
        moved[j] += [0.03, -0.02]
        changed = np.nonzero(np.abs(Rows(moved) - base) > 1e-12)[0]
        np.testing.assert_array_equal(changed, np.sort(cbf.person_rows[j]))


def _Step(controller, robot, people, velocities):
    q0 = np.array(robot.default_q, dtype=float)
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    for name in targets:
        if name.startswith("base"):
            targets[name][:2] = q0[:2] + [3.0, 0.0]
    estimate = HumanEstimate(
        ids=list(range(len(people))),
        positions=[list(p) for p in people],
        velocities=[list(v) for v in velocities],
    )
    state = FirstStep(controller, estimate, q0, np.zeros(robot.num_velocities), targets)
    assert state.record.mode == "solved"
    return state


def test_weights_follow_whether_a_person_walks_toward_the_robot():
    """A person standing and one walking away get still_slack_weight; one
    walking toward the base faster than approach_speed, human_slack_weight;
    `paper` and the default (0) keep human_slack_weight for everyone."""
    scenario, robot, controller = _Controller(still_slack_weight=1e5)
    q0 = np.array(robot.default_q, dtype=float)
    ahead = _PersonAt(robot, q0, (1, 0), 0.3, scenario.safety.human_radius)
    behind = _PersonAt(robot, q0, (-1, 0), 0.3, scenario.safety.human_radius)
    weights = {}
    for label, velocity in [
        ("standing", (0.0, 0.0)),
        ("away", (0.5, 0.0)),
        ("toward", (-0.5, 0.0)),
        ("slowly toward", (-0.03, 0.0)),
    ]:
        _Step(controller, robot, [ahead, behind], [velocity, (0.0, 0.0)])
        cbf = controller.program.cbf
        weights[label] = controller.program.linear_cost[cbf.slack[cbf.person_rows]]
        assert np.all(weights[label][1] == 1e5)  # the one behind stands
    assert np.all(weights["standing"][0] == 1e5)
    assert np.all(weights["away"][0] == 1e5)
    assert np.all(weights["slowly toward"][0] == 1e5)
    assert np.all(weights["toward"][0] == scenario.safety.human_slack_weight)
    for safety in ({"still_slack_weight": 1e5, "mode": "paper"}, {}):
        _, _, other = _Controller(**safety)
        _Step(other, robot, [ahead, behind], [(0.0, 0.0), (0.0, 0.0)])
        cbf = other.program.cbf
        cost = other.program.linear_cost[cbf.slack[cbf.person_rows]]
        assert np.all(cost == scenario.safety.human_slack_weight)


def test_a_squeezed_plan_gives_up_the_walking_persons_margin():
    """The Stretch 3 (no sideways motion) between a person standing 5 cm
    ahead of it and one walking into it from behind at 0.6 m/s, both inside
    the barrier's margin: without the option the plan pays slack on the
    standing person; with it, less, and the plan keeps farther from them."""
    scenario, robot, _ = _Controller()
    q0 = np.array(robot.default_q, dtype=float)
    r = scenario.safety.human_radius
    people = [
        _PersonAt(robot, q0, (1, 0), 0.05, r),
        _PersonAt(robot, q0, (-1, 0), 0.05, r),
    ]
    velocities = [(0.0, 0.0), (0.6, 0.0)]
    results = {}
    for weight in (0.0, 1e5):
        _, _, controller = _Controller(still_slack_weight=weight)
        state = _Step(controller, robot, people, velocities)
        cbf = controller.program.cbf
        z = state.last_solution.z
        slack = z[cbf.slack[cbf.person_rows]].sum(axis=1)
        gap = HumanDistances(robot, state.plan.q, np.array(people)[None])[:, 0] - r
        results[weight] = slack, gap
    (slack_off, gap_off), (slack_on, gap_on) = results[0.0], results[1e5]
    assert slack_off[0] > 1e-3, slack_off  # the squeeze: the standing one pays
    assert slack_on[0] < 0.5 * slack_off[0], (slack_on, slack_off)
    assert gap_on.min() > gap_off.min() + 1e-3, (gap_on.min(), gap_off.min())


@pytest.mark.parametrize(
    "text",
    [
        "{safety: {still_slack_weight: -1.0}}",
        "{safety: {approach_speed: -0.1}}",
        "{safety: {still_slack_weight: 2.0e6}}",  # above the walls' 1e6
    ],
)
def test_bad_still_slack_settings_are_refused(text):
    with pytest.raises(ScenarioError, match="still_slack_weight|approach_speed"):
        ValidateScenario(
            LoadScenario(
                filename=CROSSING,
                scenario_name="crossing_stretch3_1h",
                scenario_text=text,
            )
        )
