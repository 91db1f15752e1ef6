"""safety.turn_monitoring: speed-and-separation monitoring of the base's turn
(control/separation.py). The invariant it must keep: braking a turn at the
bound, at the yaw deceleration limit, stops before any body of the robot
reaches a person's margin; checked by turning the robot's kinematics
through the braking sweep, not by the formula."""

import numpy as np
import pytest

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.separation import TurnLimits
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.robots.planar_base import NumBaseVelocities
from sm2ith_drake.scenario import (
    ControllerConfig,
    PredictionConfig,
    SafetyConfig,
    TaskConfig,
)

RADIUS, MARGIN, DT = 0.3, 0.1, 0.2


def _Gaps(robot, qs, person):
    """Each configuration's smallest distance from any body's surface to the
    person's margin (the barrier h), by sampling the capsules' axes."""
    ends = robot.CalcKinematics(qs).capsule_points[..., :2]  # (T, C, 2, 2)
    s = np.linspace(0.0, 1.0, 401)[:, None]
    points = ends[:, :, None, 0] * (1 - s) + ends[:, :, None, 1] * s  # (T, C, S, 2)
    d = np.linalg.norm(points - person, axis=-1).min(axis=2)  # (T, C)
    return (d - robot.capsule_radii[None] - RADIUS - MARGIN).min(axis=1)


def _Limits(robot, q0, nu0, person, floor=0.0):
    return TurnLimits(
        robot,
        q0,
        nu0,
        np.array([person]),
        human_radius=RADIUS,
        human_margin=MARGIN,
        floor=floor,
        time_step=DT,
        horizon=10,
    )


@pytest.mark.parametrize("name", ["stretch3", "ridgeback_ur10"])
def test_a_turn_at_the_bound_stops_before_the_margin(name):
    """From the bound, braking at α in either direction, no configuration of
    the sweep comes inside the person's margin, for a person in 25
    directions; the bound is the closed form √(2αh/r) with h and r from the
    robot's own bodies. (Twice the bound fails this in 4–5 of the
    directions.)"""
    robot = MobileManipulator(name)
    q0 = robot.default_q.copy()
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    reach = np.linalg.norm(ends, axis=2) + robot.capsule_radii[:, None]
    r = reach.max()
    w = NumBaseVelocities(robot) - 1
    alpha = robot.nudot_upper[w]
    for bearing in np.linspace(-3.0, 3.0, 25):
        # A person whose margin is 0.05–0.3 m from the robot's nearest body.
        direction = np.array([np.cos(bearing), np.sin(bearing)])
        distances = np.linspace(0.3, 2.5, 400)
        gaps = [_Gaps(robot, q0[None], d * direction)[0] for d in distances]
        i = next(i for i, h in enumerate(gaps) if 0.05 <= h <= 0.3)
        person, h = distances[i] * direction, gaps[i]
        limits = _Limits(robot, q0, np.zeros(robot.num_velocities), person)
        assert limits is not None and limits[0] == w
        bound = limits[1][0]
        np.testing.assert_allclose(bound, np.sqrt(2 * alpha * h / r), rtol=1e-3)
        for sign in (-1.0, 1.0):
            qs = np.repeat(q0[None], 50, axis=0)
            qs[:, 2] += sign * np.linspace(0.0, bound**2 / (2 * alpha), 50)
            assert _Gaps(robot, qs, person).min() >= -1e-3, (bearing, sign)


def test_nothing_binds_far_from_people_or_without_them():
    robot = MobileManipulator("stretch3")
    q0, nu0 = robot.default_q.copy(), np.zeros(robot.num_velocities)
    assert _Limits(robot, q0, nu0, [5.0, 5.0]) is None
    assert (
        TurnLimits(
            robot,
            q0,
            nu0,
            np.zeros((0, 2)),
            human_radius=RADIUS,
            human_margin=MARGIN,
            floor=0.2,
            time_step=DT,
            horizon=10,
        )
        is None
    )


def test_the_bounds_follow_braking_from_a_faster_measured_turn():
    """A person inside the margin: the bound is the floor, but no tighter
    than braking from the measured 1 rad/s allows (feasible with ν_0
    pinned), over the yaw's stopping time."""
    robot = MobileManipulator("stretch3")
    q0 = robot.default_q.copy()
    nu0 = np.zeros(robot.num_velocities)
    w = NumBaseVelocities(robot) - 1
    nu0[w] = -1.0
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    person = ends[-1, 1] + [0.0, -0.35]  # beside the gripper
    assert _Gaps(robot, q0[None], person)[0] < 0
    w_, bounds = _Limits(robot, q0, nu0, person, floor=0.2)
    alpha = robot.nudot_upper[w]
    k = np.arange(1, bounds.size + 1)
    np.testing.assert_allclose(bounds, np.maximum(0.2, 1.0 - alpha * DT * k))
    assert bounds.size == int(np.ceil(robot.nu_upper[w] / alpha / DT - 1e-9))


def _Program(mode, monitoring=True):
    robot = MobileManipulator("stretch3")
    c = MpcController(
        robot,
        [TaskConfig(kind="base_position", target=[2.0, 0.0])],
        ControllerConfig(horizon=6),
        prediction=PredictionConfig(predictor="cvmm", max_humans=1),
        safety=SafetyConfig(mode=mode, turn_monitoring=monitoring),
    )
    q0 = robot.default_q.copy()
    nu0 = np.zeros(robot.num_velocities)
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    model = c.human_predictor
    prediction, _ = model.Predict(
        model.InitialState(),
        estimate=HumanEstimate(
            ids=[0], positions=[ends[-1, 1] + [0.0, -0.45]], velocities=[[0.0, 0.0]]
        ),
        q0=q0,
        nu0=nu0,
        warm_start_inputs=c.WarmStartInputs(c.InitialState()),
    )
    c.predictor.SetPrediction(prediction)
    lower, upper = c.program.VariableBounds(q0, nu0)
    L, w = c.program.layout, NumBaseVelocities(robot) - 1
    return upper[np.asarray(L.nu)[:, w]], robot.nu_upper[w]


def test_the_program_bounds_the_turn_in_safe_only():
    upper, top = _Program("safe")
    assert upper[0] == 0.0  # ν_0 pinned
    assert 0.2 <= upper[1] < top and np.all(upper[-2:] == top)
    for upper, top in (_Program("paper"), _Program("safe", monitoring=False)):
        assert np.all(upper[1:] == top)
