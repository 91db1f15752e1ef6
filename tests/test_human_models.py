"""Human estimation and the simulated crowd: Kalman tracking, motion capture,
the social force model and the crowd behaviours."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sm2ith_drake.humans.crowd import InitialCrowdState, StepCrowd
from sm2ith_drake.humans.instructed import PATH_LOOKAHEAD, PathVelocity
from sm2ith_drake.humans.messages import HumanDetections
from sm2ith_drake.humans.social_force import social_force_step
from sm2ith_drake.humans.tracking import HumanTracks
from sm2ith_drake.planning.sequence import TaskReferences
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import HumanConfig
from sm2ith_drake.systems.humans import CrowdSimulator, HumanEstimator, MocapSensor


def _Step(humans, state, i, **kwargs):
    """One crowd step of 0.05 s from step i's time; the robot (radius 0.5)
    stands far away and there are no walls unless ``kwargs`` say otherwise."""
    args = dict(
        time=0.05 * i,
        dt=0.05,
        robot_position=[20.0, 20.0],
        robot_velocity=[0.0, 0.0],
        robot_radius=0.5,
        obstacle_segments=np.zeros((0, 2, 2)),
        tau=2.0,
        tau_obs=0.5,
    )
    return StepCrowd(humans, state, **(args | kwargs))


def _Walker(t):
    return np.array([-2.0, 1.0]) + t * np.array([0.8, -0.3])


def test_kalman_converges_on_a_noisy_constant_velocity_walker():
    rng = np.random.default_rng(0)
    tracks = HumanTracks(measurement_noise=0.05, acceleration_noise=0.2)
    velocity_errors, position_errors = [], []
    for i in range(300):
        t = 0.05 * i
        tracks.Step(t, {7: _Walker(t) + rng.normal(scale=0.05, size=2)})
        ids, pos, vel = tracks.Estimates()
        velocity_errors.append(np.linalg.norm(vel[0] - [0.8, -0.3]))
        position_errors.append(np.linalg.norm(pos[0] - _Walker(t)))
    assert list(ids) == [7]
    # Starting from zero velocity, it converges within a few seconds, and
    # filters the 5 cm noise down.
    assert velocity_errors[0] > 0.8
    assert np.mean(velocity_errors[-100:]) < 0.1
    assert np.mean(position_errors[-100:]) < 0.03


def test_covariance_grows_during_dropouts_and_the_track_times_out():
    tracks = HumanTracks(measurement_noise=0.02, acceleration_noise=1.0, timeout=1.0)
    for i in range(40):
        tracks.Step(0.05 * i, {3: _Walker(0.05 * i)})
    traces = []
    for i in range(40, 58):  # 0.9 s without detections
        tracks.Step(0.05 * i, {})
        traces.append(np.trace(tracks.tracks[3].P))
    assert np.all(np.diff(traces) > 0)
    # Predicting through the gap keeps the walker's motion.
    np.testing.assert_allclose(tracks.tracks[3].position, _Walker(0.05 * 57), atol=0.05)
    tracks.Step(0.05 * 62, {})  # past the timeout
    assert 3 not in tracks.tracks and tracks.dropped_count == 1


def test_bad_detections_are_rejected_and_counted():
    tracks = HumanTracks(measurement_noise=0.02)
    tracks.Step(0.0, {1: [0.0, 0.0], 2: [np.nan, 1.0], 3: [1e9, 0.0]})
    assert sorted(tracks.tracks) == [1] and tracks.rejected_count == 2
    tracks.Step(0.05, {1: [40.0, 0.0]})  # an implausible jump (innovation gate)
    assert tracks.rejected_count == 3
    np.testing.assert_allclose(tracks.tracks[1].position, [0.0, 0.0], atol=1e-9)
    # New and vanished humans.
    tracks.Step(0.1, {1: [0.0, 0.0], 5: [2.0, 2.0]})
    assert sorted(tracks.tracks) == [1, 5]


def test_mocap_and_estimator_systems_in_a_diagram():
    """MocapSensor (noise, 30 % dropouts) feeding the HumanEstimator tracks a
    walker; the same seed gives the same estimate."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.framework import LeafSystem

    from sm2ith_drake.humans.messages import HumanEstimate

    class Truth(LeafSystem):
        def __init__(self):
            super().__init__()
            self.DeclareAbstractOutputPort(
                "human_truth",
                lambda: AbstractValue.Make(HumanEstimate()),
                lambda context, out: out.set_value(
                    HumanEstimate(
                        ids=[4],
                        positions=[_Walker(context.get_time())],
                        velocities=[[0.8, -0.3]],
                    )
                ),
            )

    def Run(seed):
        builder = DiagramBuilder()
        truth = builder.AddSystem(Truth())
        sensor = builder.AddSystem(
            MocapSensor(period=0.05, noise=0.03, dropout_probability=0.3, seed=seed)
        )
        est = builder.AddSystem(
            HumanEstimator(
                period=0.05,
                measurement_noise=0.03,
                acceleration_noise=0.2,
                track_timeout=1.0,
            )
        )
        builder.Connect(truth.get_output_port(), sensor.GetInputPort("human_truth"))
        builder.Connect(
            sensor.GetOutputPort("detections"), est.GetInputPort("detections")
        )
        diagram = builder.Build()
        sim = Simulator(diagram)
        sim.AdvanceTo(8.0)
        ctx = est.GetMyContextFromRoot(sim.get_context())
        frame = sensor.GetOutputPort("detections").Eval(
            sensor.GetMyContextFromRoot(sim.get_context())
        )
        assert isinstance(frame, HumanDetections)
        return est.GetOutputPort("human_estimate").Eval(ctx)

    a, b = Run(1), Run(1)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_allclose(a.velocities[0], [0.8, -0.3], atol=0.15)
    np.testing.assert_allclose(a.positions[0], _Walker(8.0), atol=0.1)


def test_social_force_reaches_goals_and_keeps_people_apart():
    p = np.array([[0.0, 0.0], [6.0, 0.05]])
    v = np.zeros((2, 2))
    goals = np.array([[6.0, 0.0], [0.0, 0.0]])
    radii = np.array([0.3, 0.3])
    gaps = []
    for _ in range(400):
        p, v = social_force_step(p, v, goals, radii, dt=0.05, max_speeds=[1.0, 1.0])
        gaps.append(np.linalg.norm(p[0] - p[1]) - 0.6)
    assert min(gaps) > 0.0
    np.testing.assert_allclose(p, goals, atol=0.25)


def test_social_force_wall_pushes_away():
    p = np.array([[0.0, 0.35]])
    wall = [np.array([[-5.0, 0.0], [5.0, 0.0]])]
    p2, v2 = social_force_step(
        p, np.zeros((1, 2)), np.array([[0.0, 0.35]]), [0.3], dt=0.05, obstacles=wall
    )
    assert v2[0, 1] > 0 and abs(v2[0, 0]) < 1e-9


def test_social_force_robot_disc_is_the_nearest_point_model_with_the_base():
    """Pushing from the base disc, or from per-person robot points that are
    all the base's centre, is the same step; a nearer point pushes harder."""
    p = np.array([[0.0, 0.9], [1.0, -0.8], [3.0, 3.0]])
    v = np.array([[0.0, -1.0], [0.0, 1.0], [0.5, 0.0]])
    goals = np.array([[0.0, -3.0], [1.0, 3.0], [5.0, 3.0]])
    radii = np.array([0.3, 0.3, 0.3])
    disc = social_force_step(
        p, v, goals, radii, dt=0.05, robot_position=[0.2, 0.0], robot_radius=0.4
    )
    points = social_force_step(
        p,
        v,
        goals,
        radii,
        dt=0.05,
        robot_points=np.tile([0.2, 0.0], (3, 1)),
        robot_point_radii=np.full(3, 0.4),
    )
    np.testing.assert_array_equal(disc[1], points[1])
    # Person 0's nearest robot point moved under them: pushed up harder.
    nearer = social_force_step(
        p,
        v,
        goals,
        radii,
        dt=0.05,
        robot_points=np.array([[0.0, 0.5], [0.2, 0.0], [0.2, 0.0]]),
        robot_point_radii=np.array([0.05, 0.4, 0.4]),
    )
    assert nearer[1][0, 1] > points[1][0, 1] + 0.1
    np.testing.assert_array_equal(nearer[1][1:], points[1][1:])


def test_social_force_people_keep_off_an_arm_sticking_out():
    """A robot (base disc 0.3 m at the origin) holds an arm 1.5 m out
    along +x; a social-force person walks across the arm at x = 1.1. Pushed
    only by the base they walk through the arm; pushed by the nearest body
    they keep off it (here they stop in front of it: the social force model
    does not plan a way round a static obstacle across its path)."""
    arm = (np.array([[[0.0, 0.0], [1.5, 0.0]]]), np.array([0.05]))
    person = HumanConfig(
        behavior="social_force", start=[1.1, 2.5], waypoints=[[1.1, -2.5]], speed=1.0
    )

    def closest(bodies):
        state = InitialCrowdState([person])
        gap = np.inf
        for i in range(200):
            state = _Step(
                [person],
                state,
                i,
                robot_position=[0.0, 0.0],
                robot_radius=0.3,
                robot_bodies=bodies,
            )
            x, y = state.positions[0]
            along = np.clip(x, 0.0, 1.5)
            gap = min(gap, np.hypot(x - along, y) - 0.05 - person.radius)
        return gap

    assert closest(None) < -0.25  # straight through the arm
    assert closest(arm) > -0.05


def _Crowd(humans, steps, robot=(10.0, 10.0), obstacles=()):
    state = InitialCrowdState(humans)
    trace = [state.positions.copy()]
    for i in range(steps):
        state = StepCrowd(
            humans,
            state,
            time=0.05 * i,
            dt=0.05,
            robot_position=robot,
            robot_velocity=[0.0, 0.0],
            robot_radius=0.5,
            obstacle_segments=np.asarray(obstacles).reshape(-1, 2, 2),
            tau=2.0,
            tau_obs=0.5,
        )
        trace.append(state.positions.copy())
    return np.array(trace)


def test_orca_crowd_passes_without_contact():
    humans = [
        HumanConfig(behavior="orca", start=[0, 0], waypoints=[[6, 0]]),
        HumanConfig(behavior="orca", start=[6, 0.1], waypoints=[[0, 0.1]]),
        HumanConfig(behavior="orca", start=[3, -3], waypoints=[[3, 3]]),
    ]
    trace = _Crowd(humans, 200)
    for i in range(3):
        for j in range(i):
            assert (
                np.min(np.linalg.norm(trace[:, i] - trace[:, j], axis=1)) > 0.6 - 1e-3
            )
    np.testing.assert_allclose(trace[-1], [[6, 0], [0, 0.1], [3, 3]], atol=0.25)


def test_scripted_and_adversarial_behaviours():
    scripted = HumanConfig(
        behavior="scripted", start=[0, 0], waypoints=[[2, 0], [2, 2]], speed=1.0
    )
    trace = _Crowd([scripted], 200)
    np.testing.assert_allclose(trace[-1, 0], [2, 2], atol=0.05)
    # Straight at the robot, stopping at contact.
    adversary = HumanConfig(behavior="adversarial", start=[0, 0], speed=1.0)
    trace = _Crowd([adversary], 200, robot=(4.0, 0.0))
    gap = np.linalg.norm(trace[:, 0] - [4.0, 0.0], axis=1) - 0.5 - adversary.radius
    assert np.all(gap >= 0.1 - 1e-9) and gap[-1] < 0.15
    assert np.all(np.abs(trace[:, 0, 1]) < 1e-9)


def _Segment(p, a, b):
    """Distance from p to the segment ab (an independent reference)."""
    d = b - a
    s = np.clip(np.dot(p - a, d) / np.dot(d, d), 0.0, 1.0)
    return np.linalg.norm(p - (a + s * d))


def _Meeting(human, robot_at, steps, *, robot_velocity=(0.0, 0.0), arm=None):
    """Steps one person with the robot's base at robot_at(t) (radius 0.5)
    and, with ``arm``, an arm capsule (radius 0.1) from the base to base +
    arm. Returns the person's positions and its surface gap to the robot at
    each state the step started from."""
    state = InitialCrowdState([human])
    trace, gaps = [state.positions[0].copy()], []
    for i in range(steps):
        base = np.asarray(robot_at(0.05 * i), dtype=float)
        bodies = None
        gap = np.linalg.norm(state.positions[0] - base) - 0.5
        if arm is not None:
            bodies = (
                np.array([[base, base], [base, base + arm]]),
                np.array([0.5, 0.1]),
            )
            tip = _Segment(state.positions[0], base, base + arm) - 0.1
            gap = min(gap, tip)
        gaps.append(gap - human.radius)
        state = StepCrowd(
            [human],
            state,
            time=0.05 * i,
            dt=0.05,
            robot_position=base,
            robot_velocity=robot_velocity,
            robot_radius=0.5,
            obstacle_segments=np.zeros((0, 2, 2)),
            tau=2.0,
            tau_obs=0.5,
            robot_bodies=bodies,
        )
        trace.append(state.positions[0].copy())
    return np.array(trace), np.array(gaps)


def test_instructed_person_keeps_its_path_while_the_robot_is_far():
    """Positions equal the scripted person's on the same path, to the bit,
    while the robot stays out of the reaction distance (here it stands 1.2 m
    beside the path: near, but not near enough)."""
    path = dict(start=[0, 0], waypoints=[[4, 0], [4, 3]], speed=1.2)
    instructed = HumanConfig(behavior="instructed", **path)
    scripted = HumanConfig(behavior="scripted", **path)
    robot = lambda t: [2.0, -2.0]  # noqa: E731  gap 2 − 0.5 − 0.3 = 1.2 m
    a, gaps = _Meeting(instructed, robot, 200)
    b, _ = _Meeting(scripted, robot, 200)
    assert np.min(gaps) > instructed.reaction_distance
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a[-1], [4, 3], atol=0.05)


@pytest.mark.parametrize("reaction_distance", [0.5, 1.0, 2.0])
def test_instructed_person_deviates_only_within_its_reaction_distance(
    reaction_distance,
):
    """Walking at a standing robot: the path is the scripted one up to the
    first state within the reaction distance, and differs right after it."""
    path = dict(start=[0, 0], waypoints=[[8, 0]], speed=1.0)
    instructed = HumanConfig(
        behavior="instructed", reaction_distance=reaction_distance, **path
    )
    a, gaps = _Meeting(instructed, lambda t: [4.0, 0.0], 240)
    b, _ = _Meeting(HumanConfig(behavior="scripted", **path), lambda t: [4.0, 0.0], 240)
    first = np.flatnonzero(np.any(a != b, axis=1))[0]  # first differing state
    # The step from state first − 1 deviated; the one before did not react.
    assert gaps[first - 1] < reaction_distance <= gaps[first - 2]
    assert np.min(gaps) > 0.0
    # Past the robot it returns to its path and reaches its goal.
    np.testing.assert_allclose(a[-1], [8, 0], atol=0.05)


def test_instructed_person_never_walks_into_an_oncoming_robot():
    """Head-on with a robot driving at it, its arm stretched toward the
    person: the person steps aside (to its right) and keeps clear of every
    body, then walks back to its path's goal."""
    human = HumanConfig(behavior="instructed", start=[0, 0], waypoints=[[8, 0]])
    trace, gaps = _Meeting(
        human,
        lambda t: [6.0 - 0.3 * t, 0.0],
        300,
        robot_velocity=(-0.3, 0.0),
        arm=np.array([-0.6, 0.0]),
    )
    assert np.min(gaps) > 0.05
    assert np.min(trace[:, 1]) < -0.5  # went around, on its right
    np.testing.assert_allclose(trace[-1], [8, 0], atol=0.05)


def test_instructed_people_keep_clear_of_each_other():
    """Three instructed people whose paths cross at one point, the robot far
    away: they pass one another without contact (told a route, not to walk
    through each other) and reach their goals; scripted people on the same
    paths overlap, so the check can fail."""
    paths = [
        dict(start=[0, 0], waypoints=[[6, 0]]),
        dict(start=[6, 0.1], waypoints=[[0, 0.1]]),
        dict(start=[3, -3], waypoints=[[3, 3]]),
    ]

    def Closest(behavior):
        trace = _Crowd([HumanConfig(behavior=behavior, **p) for p in paths], 200)
        gaps = [
            np.linalg.norm(trace[:, i] - trace[:, j], axis=1) - 0.6
            for i in range(3)
            for j in range(i)
        ]
        return np.min(gaps), trace[-1]

    assert Closest("scripted")[0] < -0.3
    gap, end = Closest("instructed")
    assert gap > -1e-3
    np.testing.assert_allclose(end, [[6, 0], [0, 0.1], [3, 3]], atol=0.25)


def test_instructed_person_off_its_path_walks_back_onto_it_and_not_through_a_wall():
    """A person who stepped aside beside a door (the wall y = 0 with a door
    |x| < 0.5, the person pressed against the wall at (0.7, −0.3)) and whose
    path runs through the door: it slides along the wall, rounds the jamb
    and regains its path, never inside a wall. Heading straight for the
    waypoint from there would cut through the wall beside the door."""
    walls = np.array([[[-2.0, 0.0], [-0.5, 0.0]], [[0.5, 0.0], [2.0, 0.0]]])
    human = HumanConfig(
        behavior="instructed", start=[0.1, -4.0], waypoints=[[-0.1, 4.0]], speed=1.2
    )
    state = InitialCrowdState([human])
    state.positions[0] = [0.7, -0.3]
    trace = [state.positions[0].copy()]
    for i in range(200):
        state = _Step([human], state, i, obstacle_segments=walls)
        trace.append(state.positions[0].copy())
    trace = np.array(trace)
    clearance = np.min([[_Segment(p, a, b) for a, b in walls] for p in trace], axis=1)
    assert np.min(clearance) > human.radius - 0.02
    np.testing.assert_allclose(trace[-1], [-0.1, 4.0], atol=0.05)
    # Back on its path (x ≈ 0.1 − 0.025 (y + 4)) well before the goal.
    on_path = np.abs(trace[:, 0] - (0.1 - 0.025 * (trace[:, 1] + 4.0))) < 0.25
    assert np.any(on_path & (trace[:, 1] > 0.3) & (trace[:, 1] < 2.0))


def test_instructed_person_beside_a_door_jamb_walks_in_past_a_robot_to_the_side():
    """The doorway's deadlock (seed 21, 1 person): the person pressed
    against the wall beside the door's jamb, its path through the door, the
    robot's base standing within its reaction distance a metre off to its
    left. The person slides along the wall into the door and on to its goal,
    clear of the robot and the walls. It used to keep right there (the rule
    for a robot ahead), which turned it into the wall for good."""
    walls = np.array([[[-1.0, 0.0], [-0.5, 0.0]], [[0.5, 0.0], [1.0, 0.0]]])
    human = HumanConfig(
        behavior="instructed", start=[0.25, -3.1], waypoints=[[-0.2, 3.1]], speed=1.5
    )
    robot = np.array([-0.45, -0.25])
    state = InitialCrowdState([human])
    state.positions[0] = [0.55, -0.3]
    gap = np.linalg.norm(state.positions[0] - robot) - 0.28 - human.radius
    assert gap < human.reaction_distance
    trace = [state.positions[0].copy()]
    for i in range(160):
        state = _Step(
            [human],
            state,
            i,
            obstacle_segments=walls,
            robot_position=robot,
            robot_radius=0.28,
        )
        trace.append(state.positions[0].copy())
    trace = np.array(trace)
    assert np.min(np.linalg.norm(trace - robot, axis=1)) > 0.28 + human.radius
    clearance = np.min([[_Segment(p, a, b) for a, b in walls] for p in trace], axis=1)
    assert np.min(clearance) > human.radius - 0.02
    assert trace[80, 1] > 0.5  # through the door within 4 s
    np.testing.assert_allclose(trace[-1], [-0.2, 3.1], atol=0.05)


def test_instructed_path_velocity_is_the_waypoints_on_the_path():
    v = np.array([0.6, 0.8])
    # On the leg (and within the tolerance of it): straight to the waypoint.
    assert PathVelocity(np.array([3.0, 4.0]), v, [0, 0], [6, 8]) is v
    assert PathVelocity(np.array([3.1, 3.9]), v, [0, 0], [6, 8]) is v
    # Off it: toward PATH_LOOKAHEAD ahead of its foot on the leg, same speed.
    off = PathVelocity(np.array([3.0 + 0.8 * 2, 4.0 - 0.6 * 2]), v, [0, 0], [6, 8])
    aim = np.array([3.0, 4.0]) + PATH_LOOKAHEAD * v
    expected = aim - [4.6, 2.8]
    np.testing.assert_allclose(off, expected / np.linalg.norm(expected))


def test_a_person_starts_when_the_robot_enters_its_phase():
    """start_phase: standing still until the sequence enters the phase, then
    start_time after it; a phase skipped within one crowd step still counts;
    with no phase known (None), nobody with a start_phase moves."""
    humans = [
        HumanConfig(
            behavior="scripted",
            start=[0, 0],
            waypoints=[[0, 9]],
            start_phase="cross",
            start_time=0.5,
        ),
        HumanConfig(
            behavior="instructed", start=[3, 0], waypoints=[[3, 9]], start_phase="back"
        ),
        HumanConfig(behavior="scripted", start=[6, 0], waypoints=[[6, 9]]),
    ]

    def Run(phase_of_time):
        """The time each person first moves (None: never)."""
        times, positions = _GatedRun(humans, phase_of_time, steps=80)
        start = InitialCrowdState(humans).positions
        before = np.concatenate([start[None], positions[:-1]])
        moved = np.any(positions != before, axis=2)  # (T, H)
        step_start = times - 0.05
        return [step_start[np.argmax(m)] if np.any(m) else None for m in moved.T]

    # "cross" entered at 1.0 s, "back" (index 2) jumped to at 2.0 s.
    starts = Run(lambda t: 0 if t < 1.0 - 1e-9 else 1 if t < 2.0 - 1e-9 else 2)
    np.testing.assert_allclose(starts, [1.5, 2.0, 0.0], atol=1e-9)
    # The sequence went straight past both phases: both start from then.
    starts = Run(lambda t: 0 if t < 0.5 - 1e-9 else 3)
    np.testing.assert_allclose(starts, [1.0, 0.5, 0.0], atol=1e-9)
    assert Run(lambda t: None)[:2] == [None, None]


def _GatedRun(humans, phase_of_time, steps=300):
    """(T,) times and (T, H, 2) positions of ``humans`` stepped with the
    sequence ("go", "cross", "back") in ``phase_of_time(t)``, the robot far
    away."""
    state = InitialCrowdState(humans)
    times, positions = [], []
    for i in range(steps):
        t = 0.05 * i
        state = _Step(
            humans,
            state,
            i,
            phases=("go", "cross", "back"),
            phase_index=phase_of_time(t),
        )
        times.append(t + 0.05)
        positions.append(state.positions)
    return np.array(times), np.array(positions)


@pytest.mark.parametrize("behavior", ["scripted", "orca", "instructed", "social_force"])
def test_a_gated_waypoint_is_walked_to_only_once_its_phase_is_entered(behavior):
    """waypoint_phases: person 0 walks to (0, 2) at once, waits there until
    "cross" is entered (4 s), crosses to (0, 5), waits again until "back"
    (9 s) and returns to (0, 2); person 1 waits at its start until "cross".
    With no phase known, no gate opens."""
    humans = [
        HumanConfig(
            behavior=behavior,
            start=[0, 0],
            waypoints=[[0, 2], [0, 5], [0, 2]],
            waypoint_phases=["", "cross", "back"],
        ),
        HumanConfig(
            behavior=behavior,
            start=[10, 0],
            waypoints=[[10, 3]],
            waypoint_phases=["cross"],
        ),
    ]
    times, p = _GatedRun(
        humans, lambda t: 0 if t < 4.0 - 1e-9 else 1 if t < 9.0 - 1e-9 else 2
    )
    a, b = p[:, 0], p[:, 1]
    before, between, after = times <= 4.0, (times > 4.0) & (times <= 9.0), times > 9.0
    # Before "cross": person 0 at its first waypoint, not heading on; person
    # 1 at its start.
    assert np.max(a[before, 1]) < 2.5
    assert np.linalg.norm(a[before][-1] - [0, 2]) < 0.3
    assert np.max(np.linalg.norm(b[before] - [10, 0], axis=1)) < 0.05
    # "cross": both walk to their gated waypoints, and person 0 waits there
    # for "back" instead of walking on.
    assert np.linalg.norm(a[between][-1] - [0, 5]) < 0.3
    assert np.min(a[between & (times > 8.0), 1]) > 4.7
    assert np.linalg.norm(b[between][-1] - [10, 3]) < 0.3
    # "back": person 0 returns.
    assert np.linalg.norm(a[after][-1] - [0, 2]) < 0.3
    # No phase known: person 0 never leaves its first waypoint, person 1
    # never leaves its start.
    _, p = _GatedRun(humans, lambda t: None)
    assert np.max(p[:, 0, 1]) < 2.5
    assert np.max(np.linalg.norm(p[:, 1] - [10, 0], axis=1)) < 0.05


def test_the_crowd_context_keeps_when_each_gate_was_entered():
    """CrowdSimulator: when a gate's phase was entered lives in the crowd's
    Context (a clone taken before it replays the same crossing), and people
    with gates need the task_references input."""
    robot = MobileManipulator("ridgeback_ur10")
    humans = [
        HumanConfig(
            behavior="scripted",
            start=[5.0, 5.0],
            waypoints=[[5.0, 6.0], [5.0, 8.0]],
            waypoint_phases=["", "cross"],
        )
    ]
    system = CrowdSimulator(
        robot, humans, obstacle_segments=np.zeros((0, 2, 2)), phases=["go", "cross"]
    )
    context = system.CreateDefaultContext()
    x = np.concatenate([robot.default_q, np.zeros(robot.num_velocities)])
    system.GetInputPort("robot_state").FixValue(context, x)
    refs = system.GetInputPort("task_references")
    refs.FixValue(context, TaskReferences(phase_index=0, phase="go"))
    first = Simulator(system, context)
    first.AdvanceTo(3.0)
    truth = system.GetOutputPort("human_truth")
    assert 5.8 < truth.Eval(context).positions[0, 1] <= 6.0 + 1e-9
    second = Simulator(system, context.Clone())
    runs = []
    for simulator in (first, second):
        own = simulator.get_mutable_context()
        refs.FixValue(own, TaskReferences(phase_index=1, phase="cross"))
        simulator.AdvanceTo(6.0)
        runs.append(own.get_abstract_state(0).get_value())
    np.testing.assert_array_equal(runs[0].positions, runs[1].positions)
    np.testing.assert_array_equal(runs[0].gate_entered, runs[1].gate_entered)
    # The gate of waypoint 1 opened at the first crowd step after 3 s.
    assert 3.0 <= runs[0].gate_entered[0, 1] <= 3.05 + 1e-9
    assert np.isnan(runs[0].gate_entered[0, 0])
    assert 7.7 < runs[0].positions[0, 1] <= 8.0 + 1e-9
    with pytest.raises(ValueError, match=r"waypoint_phases\[1\] 'cross'"):
        CrowdSimulator(robot, humans, obstacle_segments=np.zeros((0, 2, 2)))
    unconnected = system.CreateDefaultContext()
    system.GetInputPort("robot_state").FixValue(unconnected, x)
    with pytest.raises(RuntimeError, match="task_references"):
        Simulator(system, unconnected).AdvanceTo(0.1)
