"""safety.turn_monitoring: speed-and-separation monitoring of the base's turn
(control/separation.py). The invariant it must keep: braking a turn from
its bound, at the yaw deceleration limit, stops before any body of the
robot comes inside a person's margin (or deeper than it already is);
checked by turning the robot's kinematics through the braking sweep with
an independent distance (sampled capsule axes), in both directions, for a
person in 25 directions around each robot."""

import dataclasses

import numpy as np
import pytest

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.prediction.orca_kkt import PredictionConsistency
from sm2ith_drake.control.separation import SWEEP_SAMPLES, TurnLimits
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


def _Sweep(robot, q0, person, angle):
    """h along a turn in place from q0 through ``angle`` (signed)."""
    qs = np.repeat(q0[None], 200, axis=0)
    qs[:, 2] += np.linspace(0.0, angle, 200)
    return _Gaps(robot, qs, person)


@pytest.mark.parametrize("name", ["stretch3", "ridgeback_ur10"])
def test_a_turn_braked_from_its_bound_stays_out_of_the_margin(name):
    robot = MobileManipulator(name)
    q0 = robot.default_q.copy()
    nu0 = np.zeros(robot.num_velocities)
    w = NumBaseVelocities(robot) - 1
    alpha, top = robot.nudot_upper[w], robot.nu_upper[w]
    limited = 0
    for bearing in np.linspace(-3.0, 3.0, 25):
        # A person whose margin is 0.02–0.3 m from the robot's nearest body.
        direction = np.array([np.cos(bearing), np.sin(bearing)])
        distances = np.linspace(0.3, 2.5, 400)
        gaps = [_Gaps(robot, q0[None], d * direction)[0] for d in distances]
        i = next(i for i, h in enumerate(gaps) if 0.02 <= h <= 0.3)
        person = distances[i] * direction
        limits = _Limits(robot, q0, nu0, person)
        low, high = (-top, top) if limits is None else (limits[1][0], limits[2][0])
        for sign, bound in ((1.0, high), (-1.0, low)):
            sweep = _Sweep(robot, q0, person, sign * bound**2 / (2 * alpha))
            # The implementation samples the sweep: within 3 mm.
            assert sweep.min() >= -3e-3, (bearing, bound)
            if abs(bound) < top:
                limited += 1
                # Not needlessly tight: two samples further the turn enters.
                angle = (
                    bound**2 / (2 * alpha) + 2 * top**2 / (2 * alpha) / SWEEP_SAMPLES
                )
                further = _Sweep(robot, q0, person, sign * angle)
                assert further.min() < 0, (bearing, bound)
    assert limited >= 10


def test_turning_away_is_free_and_the_floor_holds():
    """A person just inside the margin beside the Stretch 3's gripper: the
    turn toward them is held to the floor, the turn away is not limited."""
    robot = MobileManipulator("stretch3")
    q0, nu0 = robot.default_q.copy(), np.zeros(robot.num_velocities)
    w = NumBaseVelocities(robot) - 1
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    tip = ends[np.argmax(np.linalg.norm(ends[:, 1], axis=1)), 1]
    side = np.array([-tip[1], tip[0]]) / np.linalg.norm(tip)  # CCW of the tip
    person = tip + 0.48 * side
    assert _Gaps(robot, q0[None], person)[0] < 0
    _, low, high = _Limits(robot, q0, nu0, person, floor=0.2)
    np.testing.assert_allclose(high, 0.2)
    np.testing.assert_allclose(low, -robot.nu_upper[w])


def test_nothing_binds_far_from_people_or_without_them():
    robot = MobileManipulator("stretch3")
    q0, nu0 = robot.default_q.copy(), np.zeros(robot.num_velocities)
    assert _Limits(robot, q0, nu0, [5.0, 5.0]) is None
    none = TurnLimits(
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
    assert none is None


def test_the_bounds_follow_braking_from_a_faster_measured_turn():
    """Turning at 1 rad/s toward a person inside the margin: the bound is
    the floor, but no tighter than braking from the measured rate at 0.8 α
    allows (feasible with ν_0 pinned, with room), over the yaw's stopping
    time."""
    robot = MobileManipulator("stretch3")
    q0 = robot.default_q.copy()
    w = NumBaseVelocities(robot) - 1
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    tip = ends[np.argmax(np.linalg.norm(ends[:, 1], axis=1)), 1]
    side = np.array([-tip[1], tip[0]]) / np.linalg.norm(tip)
    nu0 = np.zeros(robot.num_velocities)
    nu0[w] = 1.0
    _, low, high = _Limits(robot, q0, nu0, tip + 0.48 * side, floor=0.2)
    alpha = robot.nudot_upper[w]
    k = np.arange(1, high.size + 1)
    np.testing.assert_allclose(high, np.maximum(0.2, 1.0 - 0.8 * alpha * DT * k))
    assert high.size == int(np.ceil(robot.nu_upper[w] / alpha / DT - 1e-9))
    assert np.all(low == -robot.nu_upper[w])


def _Program(mode, monitoring=True, omega0=0.0, predictor="cvmm"):
    """The yaw rate's upper bounds at every knot, and its top rate, of a
    Stretch 3 controller with a person just inside the margin, CCW of its
    gripper."""
    robot = MobileManipulator("stretch3")
    c = MpcController(
        robot,
        [TaskConfig(kind="base_position", target=[2.0, 0.0])],
        ControllerConfig(horizon=6),
        prediction=PredictionConfig(predictor=predictor, max_humans=1),
        safety=SafetyConfig(mode=mode, turn_monitoring=monitoring),
    )
    q0 = robot.default_q.copy()
    nu0 = np.zeros(robot.num_velocities)
    w = NumBaseVelocities(robot) - 1
    nu0[w] = omega0
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    tip = ends[np.argmax(np.linalg.norm(ends[:, 1], axis=1)), 1]
    side = np.array([-tip[1], tip[0]]) / np.linalg.norm(tip)
    model = c.human_predictor
    prediction, _ = model.Predict(
        model.InitialState(),
        estimate=HumanEstimate(
            ids=[0], positions=[tip + 0.48 * side], velocities=[[0.0, 0.0]]
        ),
        q0=q0,
        nu0=nu0,
        warm_start_inputs=c.WarmStartInputs(c.InitialState()),
    )
    c.predictor.SetPrediction(prediction)
    lower, upper = c.program.VariableBounds(q0, nu0)
    if omega0:
        return c, c.WarmStart(c.InitialState(), q0, nu0), lower, upper
    return upper[np.asarray(c.program.layout.nu)[:, w]], robot.nu_upper[w]


def test_the_program_bounds_the_turn_in_safe_only():
    upper, top = _Program("safe")
    assert upper[0] == 0.0  # ν_0 pinned
    np.testing.assert_allclose(upper[1:5], SafetyConfig().turn_speed_floor)
    assert np.all(upper[-2:] == top)
    for upper, top in (_Program("paper"), _Program("safe", monitoring=False)):
        assert np.all(upper[1:] == top)


def test_the_warm_start_keeps_within_the_bounds():
    """Turning at 1 rad/s toward the person: the warm start (the previous
    inputs rolled out) brakes within the bounds, and stays dynamically
    consistent. (A guess outside them made stage QPs primal infeasible:
    the bench with 10 people had 5 failed steps in 200.)"""
    c, z, lower, upper = _Program("safe", omega0=1.0)
    L = c.program.layout
    nu, u = z[L.nu], z[L.u]
    assert np.all(nu >= lower[L.nu] - 1e-12) and np.all(nu <= upper[L.nu] + 1e-12)
    np.testing.assert_allclose(nu[1:] - nu[:-1], c.program.time_step * u, atol=1e-12)
    w = NumBaseVelocities(c.robot) - 1
    assert nu[1, w] < 1.0


def test_the_warm_start_predicts_the_people_along_the_bounded_turn():
    """The HumanPredictor simulated the person along the unbounded rollout;
    the warm start brakes the turn, so its people are simulated again: the
    predicted actions re-solve the person's relaxed-ORCA QPs along the
    bounded plan. (Left as predicted, they do not, and the stage QPs
    linearized there were primal infeasible in the doorway.)"""
    c, z, _, _ = _Program("safe", omega0=1.0, predictor="orca_kkt")
    L = c.program.layout
    assert np.max(PredictionConsistency(c.predictor, z, L)) < 1e-6
    stale = z.copy()
    c.predictor.WarmStart(stale)  # the prediction's people, robot as in z
    assert np.max(PredictionConsistency(c.predictor, stale, L)) > 1e-3


def test_a_step_the_turn_bounds_leave_infeasible_goes_without_them():
    """The first stage fails while the turn is bounded (a stage solver that
    refuses bounded turns stands in for the doorway jams' infeasible QPs):
    the hierarchy solves the step again without the turn bounds, and
    succeeds; without monitoring nothing is solved twice."""
    c, z, lower, upper = _Program("safe", omega0=1.0)
    w = NumBaseVelocities(c.robot) - 1
    col = np.asarray(c.program.layout.nu)[1, w]
    top = c.robot.nu_upper[w]
    seen = []

    class Refusing:
        def __init__(self, solver):
            self.solver = solver

        def Solve(self, point, *, upper, **kwargs):
            seen.append(upper[col])
            result = self.solver.Solve(point, upper=upper, **kwargs)
            if upper[col] < top:
                return dataclasses.replace(result, success=False, status="refused")
            return result

    solver = c.solver
    solver.stage_solvers = [Refusing(s) for s in solver.stage_solvers]
    targets = {t.name: np.asarray(t.target, dtype=float) for t in c.tasks}
    q0, nu0 = c.robot.default_q.copy(), z[c.program.layout.nu[0]]
    solution = solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z)
    assert solution.success
    assert seen[0] < top and seen[-1] == top
