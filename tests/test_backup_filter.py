"""The backup-trajectory safety filter (control/backup.py,
``safety.backup_filter``): a command is judged by the whole motion it
commits the robot to (one period, then braking to a standstill) against
people moving on at their measured velocities."""

import dataclasses

import numpy as np
import pytest
from first_prediction import FirstStep

from sm2ith_drake.control.backup import (
    BackupFilter,
    BrakingAcceleration,
    CommittedMotion,
)
from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.humans.robot_view import HumanDistances, WallDistances
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.scenario_loader import LoadScenario, MakeRobot

CROSSING = GetDiagramsDir() / "crossing.scenarios.yaml"


@pytest.fixture(scope="module")
def ridgeback():
    scenario = LoadScenario(
        filename=CROSSING, scenario_name="crossing_ridgeback_ur10_1h"
    )
    return scenario, MakeRobot(scenario)


def _Gap(robot, q, position):
    return HumanDistances(robot, q[None], np.array([[position]]))[0, 0]


def _PersonAhead(robot, q0, reach, h0):
    """A point straight ahead of the robot (+x) at barrier value h0."""
    ahead = np.array([3.0, 0.0])
    while _Gap(robot, q0, ahead) - reach > h0:
        ahead[0] -= 0.0005
    return ahead


def _WallAhead(robot, q0, distance):
    """A wall across the +x direction, ``distance`` from the robot."""

    def Wall(x):
        return np.array([[[x, -2.0], [x, 2.0]]])

    x = 3.0
    while WallDistances(robot, q0[None], Wall(x))[0, 0] > distance:
        x -= 0.0005
    return Wall(x)


def _Filter(scenario, robot, walls=()):
    """The filter with the barrier's margin, so h is the DT-CBF's."""
    margin = scenario.safety.human_margin
    check = BackupFilter(
        robot,
        period=0.2,
        human_radius=scenario.safety.human_radius,
        margin=margin,
        walls=walls,
    )
    return check, scenario.safety.human_radius + margin


def test_committed_motion_brakes_to_rest_as_the_model_does(ridgeback):
    _, robot = ridgeback
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 1.0
    states = CommittedMotion(robot, q0, nu0, np.zeros_like(nu0), 0.2)
    # One period at 1 m/s, then 1 m/s braked at 1 m/s² (five periods):
    # 0.2 + 0.5 m along x, sampled four times a period.
    assert len(states) == 6 * 4
    np.testing.assert_allclose(states[-1][0] - q0[0], 0.7, atol=1e-9)
    np.testing.assert_allclose(states[-1][1:], q0[1:], atol=1e-12)
    # At rest and braking: no motion at all.
    assert len(CommittedMotion(robot, q0, np.zeros_like(nu0), None, 0.2)) == 0


def test_a_command_is_judged_by_its_stopping_distance(ridgeback):
    """Driving at 1 m/s toward a person standing 0.68 m outside the margin:
    one more period at that speed keeps the DT-CBF's one-period rate (the
    check a stale plan's replay gets), but the braking after it ends inside
    the margin, which braking at once does not."""
    scenario, robot = ridgeback
    check, reach = _Filter(scenario, robot)
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 1.0
    ahead = _PersonAhead(robot, q0, reach, 0.68)
    standing = HumanEstimate(ids=[1], positions=[ahead], velocities=[[0.0, 0.0]])
    hold = np.zeros(robot.num_velocities)
    controller = MpcController.FromScenario(robot, scenario)
    assert controller.ReplayIsSafe(q0, nu0, hold, standing)
    assert not check.Admits(q0, nu0, hold, standing)
    assert check.Admits(q0, nu0, BrakingAcceleration(robot, nu0, 0.2), standing)
    # The same command with the person 1 m further on is fine.
    farther = HumanEstimate(
        ids=[1], positions=[ahead + [1.0, 0.0]], velocities=[[0.0, 0.0]]
    )
    assert check.Admits(q0, nu0, hold, farther)
    # Or with the person walking away faster than the robot drives.
    leaving = HumanEstimate(ids=[1], positions=[ahead], velocities=[[1.2, 0.0]])
    assert check.Admits(q0, nu0, hold, leaving)
    # Unless people are held where measured (React's filter).
    held = BackupFilter(
        robot, period=0.2, human_radius=0.3, margin=0.1, people_move=False
    )
    assert not held.Admits(q0, nu0, hold, leaving)


def test_inside_the_margin_no_nearer_than_braking(ridgeback):
    """A person walking at a robot at rest, already inside the margin:
    backing away passes (it comes no nearer than braking, i.e. standing),
    driving toward them does not."""
    scenario, robot = ridgeback
    check, reach = _Filter(scenario, robot)
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    ahead = _PersonAhead(robot, q0, reach, -0.02)
    walking = HumanEstimate(ids=[1], positions=[ahead], velocities=[[-0.5, 0.0]])
    back = np.zeros(robot.num_velocities)
    back[0] = -1.0
    toward = -back
    assert check.Admits(q0, nu0, back, walking)
    assert not check.Admits(q0, nu0, toward, walking)
    assert check.Admits(q0, nu0, np.zeros_like(nu0), walking)  # standing


def test_braking_at_once_always_passes(ridgeback):
    """The filter's own fallback is admitted from any state: the invariant
    that makes it a filter, not a new failure mode."""
    scenario, robot = ridgeback
    check, _ = _Filter(scenario, robot)
    rng = np.random.default_rng(0)
    q0 = np.array(robot.default_q, dtype=float)
    for _ in range(20):
        nu0 = rng.uniform(robot.nu_lower, robot.nu_upper)
        people = HumanEstimate(
            ids=[1, 2],
            positions=q0[:2] + rng.uniform(-1.5, 1.5, (2, 2)),
            velocities=rng.uniform(-1.0, 1.0, (2, 2)),
        )
        assert check.Admits(q0, nu0, BrakingAcceleration(robot, nu0, 0.2), people)


def test_nobody_or_a_lost_track_passes(ridgeback):
    scenario, robot = ridgeback
    check, _ = _Filter(scenario, robot)
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    u = np.ones(robot.num_velocities)
    assert check.Admits(q0, nu0, u, None)
    assert check.Admits(q0, nu0, u, HumanEstimate(ids=[], positions=[], velocities=[]))
    lost = HumanEstimate(ids=[1], positions=[[np.nan, np.nan]], velocities=[[0, 0]])
    assert check.Admits(q0, nu0, u, lost)


class _TowardThePerson:
    """Wraps the real solver (the declared seam) and overwrites the plan's
    first input with full acceleration forward."""

    def __init__(self, solver):
        self.solver = solver

    def Solve(self, **kwargs):
        solution = self.solver.Solve(**kwargs)
        u = solution.u.copy()
        u[0] = 0.0
        u[0, 0] = 1.0
        return dataclasses.replace(solution, u=u)


@pytest.mark.parametrize("mode", ["safe", "paper"])
def test_controller_brakes_where_the_filter_refuses(ridgeback, mode):
    scenario, robot = ridgeback
    safety = dataclasses.replace(
        scenario.safety, backup_filter=True, backup_margin=0.1, mode=mode
    )
    controller = MpcController.FromScenario(
        robot, dataclasses.replace(scenario, safety=safety)
    )
    controller.solver = _TowardThePerson(controller.solver)
    reach = safety.human_radius + safety.backup_margin
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 0.5
    ahead = _PersonAhead(robot, q0, reach, 0.3)
    standing = HumanEstimate(ids=[1], positions=[ahead], velocities=[[0.0, 0.0]])
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    state = FirstStep(controller, standing, q0, nu0, targets)
    if mode == "safe":
        assert state.record.mode == "filtered"
        assert state.counters.filtered_steps == 1
        np.testing.assert_allclose(
            state.command_u, BrakingAcceleration(robot, nu0, controller.period)
        )
        assert state.plan is not None  # kept for the next warm start
    else:  # the paper's formulation has no filter
        assert state.record.mode == "solved"
        assert state.command_u[0] == 1.0


def test_walls_count(ridgeback):
    """Driving at a wall whose margin braking at once keeps out of, but one
    more period at speed does not: refused, like a person."""
    scenario, robot = ridgeback
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    nu0[0] = 1.0
    hold = np.zeros(robot.num_velocities)
    # A wall across the path, 0.6 m + margin beyond the robot's front:
    # braking at once (0.5 m) stays out, one more period first does not.
    wall = _WallAhead(robot, q0, 0.1 + 0.65)
    check = BackupFilter(
        robot, period=0.2, human_radius=0.3, margin=0.1, walls=wall, wall_margin=0.1
    )
    nobody_near = HumanEstimate(ids=[1], positions=[[-9.0, 9.0]], velocities=[[0, 0]])
    assert not check.Admits(q0, nu0, hold, nobody_near)
    assert check.Admits(q0, nu0, BrakingAcceleration(robot, nu0, 0.2), nobody_near)


@pytest.mark.parametrize("predictor", ["orca_kkt", "cvmm", "react"])
def test_react_filter_holds_people_where_measured(ridgeback, predictor):
    scenario, robot = ridgeback
    scenario = dataclasses.replace(
        scenario,
        safety=dataclasses.replace(scenario.safety, backup_filter=True),
        prediction=dataclasses.replace(scenario.prediction, predictor=predictor),
    )
    controller = MpcController.FromScenario(robot, scenario)
    assert controller.backup_filter.people_move == (predictor != "react")
