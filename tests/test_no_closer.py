"""safety.no_closer_gap: a person measured within the gap of the robot's
nearest body is held no closer where they stand, over the base's stopping
time, for every method in the `safe` variant; people beyond the gap, and
the `paper` variant, are untouched."""

import dataclasses

import numpy as np
import pytest
from first_prediction import FirstStep

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.humans.robot_view import HumanDistances
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.scenario_loader import LoadScenario, MakeRobot

CROSSING = GetDiagramsDir() / "crossing.scenarios.yaml"


def _Setup():
    scenario = LoadScenario(
        filename=CROSSING, scenario_name="crossing_ridgeback_ur10_1h"
    )
    return scenario, MakeRobot(scenario)


def _PersonAhead(robot, q0, gap, radius):
    """A point on the +x axis whose surface gap to the robot is ``gap``."""
    p = np.array([3.0, 0.0])
    while HumanDistances(robot, q0[None], p[None, None])[0, 0] - radius > gap:
        p[0] -= 0.002
    return p


def _Plan(
    scenario, robot, person, *, predictor="orca_kkt", velocity=(0.0, 0.0), **safety
):
    """The first step's plan, the robot standing, its base goal beyond a
    person at ``person`` measured at ``velocity`` (standing still by
    default); h of the robot against where the person is at every knot, and
    the program's DT-CBF group."""
    controller = MpcController(
        robot,
        scenario.tasks,
        scenario.controller,
        prediction=dataclasses.replace(scenario.prediction, predictor=predictor),
        safety=dataclasses.replace(scenario.safety, **safety),
    )
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    for name in targets:
        if name.startswith("base"):
            targets[name][:2] = person + [3.0, 0.0]
    q0 = np.array(robot.default_q, dtype=float)
    estimate = HumanEstimate(ids=[1], positions=[person], velocities=[list(velocity)])
    state = FirstStep(controller, estimate, q0, np.zeros(robot.num_velocities), targets)
    assert state.record.mode == "solved"
    d = HumanDistances(robot, state.plan.q, person[None, None])[:, 0]
    return d - scenario.safety.human_radius, controller.program.cbf


@pytest.mark.parametrize("predictor", ["orca_kkt", "cvmm", "react"])
def test_a_near_person_is_not_closed_in_on(predictor):
    """A person 15 cm from the robot (outside the barrier's 10 cm margin),
    standing, with the base's goal beyond them: with a 20 cm gap every
    method's plan keeps its distance to where they stand from falling over
    the base's stopping time (6 steps on the Ridgeback–UR10); without the
    option SM²ITH's plan closes in (the barrier and the guard allow down to
    the margin)."""
    scenario, robot = _Setup()
    q0 = np.array(robot.default_q, dtype=float)
    reach = scenario.safety.human_radius
    person = _PersonAhead(robot, q0, 0.15, reach)
    gap, cbf = _Plan(scenario, robot, person, predictor=predictor, no_closer_gap=0.2)
    assert cbf.near_rows.size == 6 * len(cbf.static_p0)  # per slot
    assert np.all(np.diff(gap[:7]) >= -2e-3), gap[:7]
    if predictor == "orca_kkt":
        gap_off, cbf_off = _Plan(scenario, robot, person, predictor=predictor)
        assert cbf_off.near_rows.size == 0
        assert gap_off[:7].min() < gap_off[0] - 5e-3, gap_off[:7]


def test_people_beyond_the_gap_and_the_paper_variant_are_untouched():
    """A person 0.3 m away, beyond a 0.1 m gap: the plan is the one without
    the option (the rows hold trivially); in `paper` there are no rows."""
    scenario, robot = _Setup()
    q0 = np.array(robot.default_q, dtype=float)
    person = _PersonAhead(robot, q0, 0.3, scenario.safety.human_radius)
    on, _ = _Plan(scenario, robot, person, no_closer_gap=0.1)
    off, _ = _Plan(scenario, robot, person)
    np.testing.assert_allclose(on, off, atol=1e-4)  # the solver's tolerance
    _, cbf = _Plan(scenario, robot, person, no_closer_gap=0.1, mode="paper")
    assert cbf.near_rows.size == 0


def test_no_closer_speed_holds_only_people_standing():
    """With safety.no_closer_speed, only people measured slower than it are
    held: a person standing 15 cm ahead is held as without it (their gap
    does not fall over the stopping time), and one walking away ahead at
    0.6 m/s is not (the plan is the one without the option, while with
    every near person held it differs)."""
    scenario, robot = _Setup()
    q0 = np.array(robot.default_q, dtype=float)
    person = _PersonAhead(robot, q0, 0.15, scenario.safety.human_radius)
    still, _ = _Plan(scenario, robot, person, no_closer_gap=0.2, no_closer_speed=0.2)
    assert np.all(np.diff(still[:7]) >= -2e-3), still[:7]
    away = (0.6, 0.0)
    off, _ = _Plan(scenario, robot, person, velocity=away, no_closer_gap=0.0)
    fast, cbf = _Plan(
        scenario, robot, person, velocity=away, no_closer_gap=0.2, no_closer_speed=0.2
    )
    every, _ = _Plan(scenario, robot, person, velocity=away, no_closer_gap=0.2)
    assert cbf.near_rows.size > 0  # the rows are there, and hold trivially
    np.testing.assert_allclose(fast, off, atol=1e-4)  # the solver's tolerance
    assert np.abs(every - off).max() > 5e-3, np.abs(every - off).max()
