"""The preferred velocity turned off the walls (prediction.steer_around_walls)."""

import numpy as np

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.prediction.intent import SteerAroundWalls
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import (
    ControllerConfig,
    ObstacleConfig,
    PredictionConfig,
    SafetyConfig,
    TaskConfig,
)

# The doorway study's walls: a corridor 2 m wide, a wall across it at y = 0
# with a door at |x| < 0.5.
DOOR = np.array(
    [
        [[-1.0, -5.0], [-1.0, 5.0]],
        [[1.0, -5.0], [1.0, 5.0]],
        [[-1.0, 0.0], [-0.5, 0.0]],
        [[0.5, 0.0], [1.0, 0.0]],
    ]
)
RADIUS = 0.3
LOOKAHEAD = 2.0


def _Clearance(p, v, lookahead=LOOKAHEAD, samples=2001):
    """The line's least distance to the walls, by dense sampling (an
    independent check of the closed-form segment distances)."""
    points = p + np.linspace(0.0, lookahead, samples)[:, None] * v
    a, b = DOOR[:, 0], DOOR[:, 1]
    ab = b - a
    s = np.clip(
        np.einsum("psk,sk->ps", points[:, None, :] - a, ab) / np.sum(ab * ab, 1), 0, 1
    )
    closest = a + s[..., None] * ab
    return np.min(np.linalg.norm(points[:, None, :] - closest, axis=-1))


def _Rotate(v, angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def test_a_person_heading_beside_the_door_is_turned_through_it():
    p, v = np.array([0.6, -1.5]), np.array([0.1, 1.4])
    assert _Clearance(p, v) < RADIUS  # straight on: into the wall
    out = SteerAroundWalls(p[None], v[None], DOOR, RADIUS, lookahead=LOOKAHEAD)[0]
    np.testing.assert_allclose(np.linalg.norm(out), np.linalg.norm(v))
    assert _Clearance(p, out) >= RADIUS - 1e-3
    # Toward the door's centre (left), and the smallest such turn: 5° less
    # either way is blocked.
    angle = np.arctan2(v[0] * out[1] - v[1] * out[0], v @ out)
    assert angle > 0
    step = np.deg2rad(5.0)
    assert _Clearance(p, _Rotate(v, angle - step)) < RADIUS
    assert _Clearance(p, _Rotate(v, -(angle - step))) < RADIUS
    # On the turned line the person is through the door within the horizon.
    assert (p + LOOKAHEAD * out)[1] > 0.5


def test_free_slow_and_wall_free_lines_are_kept():
    positions = np.array([[0.0, -2.0], [0.7, -1.0], [-0.8, 2.0]])
    velocities = np.array([[0.0, 1.0], [0.0, 0.02], [0.0, 1.0]])
    out = SteerAroundWalls(positions, velocities, DOOR, RADIUS, lookahead=LOOKAHEAD)
    # Through the door's middle; too slow to tell; along the corridor wall.
    np.testing.assert_array_equal(out, velocities)
    np.testing.assert_array_equal(
        SteerAroundWalls(
            positions, velocities, np.zeros((0, 2, 2)), RADIUS, lookahead=LOOKAHEAD
        ),
        velocities,
    )
    # Against the wall beside the door, pushing into it: turned along the
    # wall (the person may walk along what they already touch), toward the
    # nearer side first (the smallest turn; both are 90° here, left first).
    against = SteerAroundWalls(
        [[0.7, -RADIUS]], [[0.0, 0.5]], DOOR, RADIUS, lookahead=LOOKAHEAD
    )[0]
    np.testing.assert_allclose(against, [-0.5, 0.0], atol=1e-12)
    # Boxed in: every direction within the turn limit is blocked, so the
    # v_pref is kept.
    box = np.array(
        [
            [[-0.4, -0.4], [0.4, -0.4]],
            [[0.4, -0.4], [0.4, 0.4]],
            [[0.4, 0.4], [-0.4, 0.4]],
            [[-0.4, 0.4], [-0.4, -0.4]],
        ]
    )
    np.testing.assert_array_equal(
        SteerAroundWalls([[0.0, 0.0]], [[1.0, 0.0]], box, RADIUS, lookahead=2.0),
        [[1.0, 0.0]],
    )


def test_the_mpc_predicts_with_the_turned_preferred_velocity():
    """Through the predictor: with the option the ORCA model's v_pref (which
    the KKT embedding uses) is the turned one; without, the measurement."""
    robot = MobileManipulator("stretch3")
    walls = [ObstacleConfig(vertices=s.tolist()) for s in DOOR]
    person = HumanEstimate(ids=[3], positions=[[0.6, -1.5]], velocities=[[0.1, 1.4]])
    q0 = np.array(robot.default_q, dtype=float)
    q0[:3] = [0.0, -3.0, np.pi / 2]
    v_pref = {}
    for steer in (False, True):
        c = MpcController(
            robot,
            [TaskConfig(kind="base_position", target=[0.0, 1.5])],
            ControllerConfig(),
            prediction=PredictionConfig(
                predictor="orca_kkt", max_humans=1, steer_around_walls=steer
            ),
            safety=SafetyConfig(),
            obstacles=walls,
        )
        model = c.human_predictor
        prediction, _ = model.Predict(
            model.InitialState(),
            estimate=person,
            q0=q0,
            nu0=np.zeros(robot.num_velocities),
            warm_start_inputs=c.WarmStartInputs(c.InitialState()),
        )
        v_pref[steer] = prediction.preferred_velocities[0]
        new = c.Step(
            c.InitialState(),
            prediction=prediction,
            time_now=0.0,
            q0=q0,
            nu0=np.zeros(robot.num_velocities),
            targets={"base_position": np.array([0.0, 1.5])},
        )
        assert new.record.mode == "solved", new.record.status
        np.testing.assert_allclose(c.predictor.v_pref[0], v_pref[steer])
    np.testing.assert_allclose(v_pref[False], [0.1, 1.4])
    expected = SteerAroundWalls(
        [[0.6, -1.5]], [[0.1, 1.4]], DOOR, RADIUS, lookahead=LOOKAHEAD
    )
    np.testing.assert_allclose(v_pref[True], expected[0])
    assert not np.allclose(v_pref[True], v_pref[False])
