"""The recovery's route for the base (control/route.py): its clearance
against an independent closest-point routine, its costs against closed
forms in the open, and a way out of the corner beside a door that driving
at the goal does not find."""

import numpy as np
import pytest

from sm2ith_drake.control.route import (
    BACKWARD,
    FORWARD,
    SIDEWAYS,
    START_RADIUS,
    TURN,
    Footprint,
    FootprintClearance,
    PlanRoute,
)
from sm2ith_drake.geometry import segment_closest_points
from sm2ith_drake.robots.mobile_manipulator import MobileManipulator

# The Stretch 3 doorway (diagrams/doorway.scenarios.yaml): corridor walls at
# x = ±1, a wall across at y = 0 with a 1 m door.
DOOR = np.array(
    [
        [[-1.0, -5.0], [-1.0, 5.0]],
        [[1.0, -5.0], [1.0, 5.0]],
        [[-1.0, 0.0], [-0.5, 0.0]],
        [[0.5, 0.0], [1.0, 0.0]],
    ]
)
# A disc-shaped base and a bar ahead of it (m).
BAR = Footprint(
    segments=np.array([[[0.0, 0.0], [0.0, 0.0]], [[0.2, 0.0], [0.6, 0.0]]]),
    radii=np.array([0.2, 0.05]),
)


def _Reference(footprint, pose, walls, discs):
    """The clearance by segment_closest_points (3D, lifted), point by point."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    R = np.array([[c, -s], [s, c]])
    best = np.inf
    for (a, b), r in zip(footprint.segments, footprint.radii, strict=True):
        A, B = pose[:2] + R @ a, pose[:2] + R @ b
        for w in walls:
            _, _, p, q = segment_closest_points(
                np.r_[A, 0.0], np.r_[B, 0.0], np.r_[w[0], 0.0], np.r_[w[1], 0.0]
            )
            best = min(best, np.linalg.norm(p - q) - r)
        for x, y, rd in discs:
            _, _, p, q = segment_closest_points(
                np.r_[A, 0.0], np.r_[B, 0.0], np.r_[x, y, 0.0], np.r_[x, y, 0.0]
            )
            best = min(best, np.linalg.norm(p - q) - r - rd)
    return best


def test_footprint_clearance_matches_a_closest_point_reference():
    rng = np.random.default_rng(3)
    for _ in range(20):
        footprint = Footprint(
            segments=rng.uniform(-0.5, 0.5, (3, 2, 2)), radii=rng.uniform(0, 0.2, 3)
        )
        walls = rng.uniform(-2, 2, (4, 2, 2))
        discs = np.column_stack([rng.uniform(-2, 2, (2, 2)), rng.uniform(0, 0.4, 2)])
        poses = np.column_stack([rng.uniform(-1, 1, (5, 2)), rng.uniform(-4, 4, 5)])
        got = FootprintClearance(footprint, poses, walls, discs)
        want = [_Reference(footprint, p, walls, discs) for p in poses]
        np.testing.assert_allclose(got, want, atol=1e-9)


def _Check(route, footprint, walls, start, goal, tolerance, clearance, discs=None):
    """A route starts at ``start``, makes one lattice move at a time, ends
    within ``tolerance`` of ``goal``, and keeps ``clearance`` (exactly,
    beyond START_RADIUS of the start)."""
    assert route is not None
    np.testing.assert_allclose(route.poses[0], start)
    assert np.linalg.norm(route.poses[-1, :2] - goal) <= tolerance + 1e-9
    steps = np.diff(route.poses, axis=0)
    moved = np.linalg.norm(steps[:, :2], axis=1) > 1e-9
    turned = np.abs(steps[:, 2]) > 1e-9
    assert not np.any(moved & turned), "a move either turns or translates"
    assert np.all(moved | turned)
    assert np.all((route.moves == TURN) == ~moved)
    away = np.linalg.norm(route.poses[:, :2] - start[:2], axis=1) > START_RADIUS
    clear = FootprintClearance(footprint, route.poses[away], walls, discs)
    assert np.all(clear >= clearance - 1e-9)


def test_in_the_open_the_route_is_the_straight_drive_with_its_closed_form_cost():
    start, goal = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0])
    route = PlanRoute(
        BAR, np.zeros((0, 2, 2)), start, goal, goal_tolerance=0.01, clearance=0.05
    )
    _Check(route, BAR, np.zeros((0, 2, 2)), start, goal, 0.01, 0.05)
    assert route.cost == pytest.approx(1.0)
    assert set(route.moves[1:]) == {FORWARD}


@pytest.mark.parametrize(
    "holonomic, cost", [(False, 1.0 + 0.3 * np.pi / 2), (True, 1.0)]
)
def test_facing_away_a_differential_drive_turns_a_holonomic_base_steps_aside(
    holonomic, cost
):
    """From facing +y to a goal 1 m along +x: a quarter turn (0.3 m/rad)
    and 1 m ahead, or, for a holonomic base, 1 m sideways."""
    start, goal = np.array([0.0, 0.0, np.pi / 2]), np.array([1.0, 0.0])
    route = PlanRoute(
        BAR,
        np.zeros((0, 2, 2)),
        start,
        goal,
        goal_tolerance=0.01,
        clearance=0.05,
        holonomic=holonomic,
    )
    _Check(route, BAR, np.zeros((0, 2, 2)), start, goal, 0.01, 0.05)
    assert route.cost == pytest.approx(cost)
    if holonomic:
        assert set(route.moves[1:]) == {SIDEWAYS}


def _Stretch(arm=(0.58, 0.06, -0.19, -0.17)):
    robot = MobileManipulator("stretch3")
    kin = robot.CalcKinematics(np.r_[0.0, 0.0, 0.0, arm][None])
    return Footprint(kin.capsule_points[0, :, :, :2], robot.capsule_radii)


def test_from_the_corner_beside_the_door_the_route_backs_off_and_goes_through():
    """The Stretch 3 where a doorway run of SM²ITH ended (3 people, seed
    7): base behind the left jamb, facing up and to the right, arm out to
    its right. Driving at the goal runs its base into the jamb's end."""
    footprint = _Stretch()
    start, goal = np.array([-0.56, -0.24, 0.9]), np.array([0.0, 1.5])
    route = PlanRoute(footprint, DOOR, start, goal, goal_tolerance=0.2, clearance=0.07)
    _Check(route, footprint, DOOR, start, goal, 0.2, 0.07)
    assert BACKWARD in route.moves or np.any(route.poses[:, 0] > -0.5 + 0.3)
    # It passes the wall through the door.
    crossing = np.nonzero(np.diff(np.sign(route.poses[:, 1])))[0]
    assert len(crossing) and np.all(np.abs(route.poses[crossing, 0]) < 0.5)


def test_a_person_standing_in_the_door_leaves_no_route_and_is_kept_clear_of():
    footprint = _Stretch()
    start, goal = np.array([0.0, -1.0, np.pi / 2]), np.array([0.0, 1.5])
    person = np.array([[0.0, 0.0, 0.4]])
    assert (
        PlanRoute(
            footprint,
            DOOR,
            start,
            goal,
            goal_tolerance=0.2,
            clearance=0.05,
            discs=person,
        )
        is None
    )
    aside = np.array([[-0.6, -0.6, 0.4]])
    route = PlanRoute(
        footprint, DOOR, start, goal, goal_tolerance=0.2, clearance=0.05, discs=aside
    )
    _Check(route, footprint, DOOR, start, goal, 0.2, 0.05, aside)


def test_bad_input_gets_a_clear_error():
    with pytest.raises(ValueError, match="finite"):
        PlanRoute(BAR, DOOR, [np.nan, 0, 0], [0, 1], goal_tolerance=0.1, clearance=0.0)
    with pytest.raises(ValueError, match="exceeds"):
        PlanRoute(BAR, DOOR, [0, 0, 0], [50, 50], goal_tolerance=0.1, clearance=0.0)
