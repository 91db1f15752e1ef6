"""Why ORCA people touch a robot from behind (README: Contact in the `safe`
variant).

ORCA people leave half of every avoidance to the other agent. A robot that
drives away from a faster person at its top speed cannot take its half, so
the person closes to within a millimetre and follows there; when the robot
then slows down, as it must at a door or a goal, the person walks into it.
These tests show it with RVO2 itself (the pyrvo bindings) and with the
studies' own ORCA people (``StepCrowd``), with no controller in the loop:
the robot is a disc driven along a fixed speed profile. They are the
reason the issue's bar of 0 contacts with ORCA people cannot be met by
a robot that must slow down with a person close behind and has no room
to step aside (the Stretch 3 in a 1 m door), whichever its controller."""

import numpy as np
import pytest

from sm2ith_drake.humans.crowd import InitialCrowdState, StepCrowd
from sm2ith_drake.scenario import HumanConfig

ROBOT_RADIUS = 0.28  # the Stretch 3's base disc (0.56 m across)
PERSON_RADIUS = 0.25
TOP_SPEED = 0.3  # the Stretch 3's base (m/s)
PERSON_SPEED = 1.2


def _LeadSpeed(t, brake_at, deceleration):
    """The robot drives at its top speed, then brakes to a stop."""
    if brake_at is None or t < brake_at:
        return TOP_SPEED
    return max(0.0, TOP_SPEED - deceleration * (t - brake_at))


def _Rvo2Gaps(brake_at=None, deceleration=0.5, dt=0.1, duration=15.0):
    pyrvo = pytest.importorskip("pyrvo")
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(dt)
    # The robot sees nobody (max_neighbors 0), so it walks its preferred
    # velocity exactly; the person is an ordinary RVO2 agent (τ = 2 s).
    sim.add_agent((0.0, 0.0), 10.0, 0, 2.0, 0.5, ROBOT_RADIUS, 1.0, (0.0, TOP_SPEED))
    sim.add_agent(
        (0.0, -2.0), 10.0, 10, 2.0, 0.5, PERSON_RADIUS, PERSON_SPEED, (0.0, 1.0)
    )
    gaps = []
    for k in range(int(round(duration / dt))):
        speed = _LeadSpeed(k * dt, brake_at, deceleration)
        sim.set_agent_pref_velocity(0, (0.0, speed))
        sim.set_agent_pref_velocity(1, (0.0, PERSON_SPEED))
        sim.do_step()
        robot = np.array(sim.get_agent_position(0).to_tuple())
        person = np.array(sim.get_agent_position(1).to_tuple())
        gaps.append(np.linalg.norm(robot - person) - ROBOT_RADIUS - PERSON_RADIUS)
    return np.array(gaps)


def _CrowdGaps(brake_at=None, deceleration=0.5, dt=0.05, duration=15.0, walls=1.0):
    """The studies' ORCA person (stepped every 0.05 s, as ``CrowdSimulator``
    steps it) behind the robot's disc in a corridor ``walls`` wide (the
    doorway's door is 1 m). As in the studies, the person sees the robot's
    velocity at the start of each step, and the robot moves on its own
    speed profile during it."""
    human = HumanConfig(
        behavior="orca",
        start=[0.0, -2.0],
        waypoints=[[0.0, 100.0]],
        speed=PERSON_SPEED,
        radius=PERSON_RADIUS,
    )
    w = walls / 2
    segments = np.array([[[-w, -50.0], [-w, 150.0]], [[w, -50.0], [w, 150.0]]])
    state = InitialCrowdState([human])
    robot = np.zeros(2)
    gaps = []
    for k in range(int(round(duration / dt))):
        t = k * dt
        state = StepCrowd(
            [human],
            state,
            time=t,
            dt=dt,
            robot_position=robot,
            robot_velocity=[0.0, _LeadSpeed(t, brake_at, deceleration)],
            robot_radius=ROBOT_RADIUS,
            obstacle_segments=segments,
            tau=2.0,
            tau_obs=0.5,
        )
        # The robot's own motion over the step (midpoint rule, 10 substeps).
        for i in range(10):
            robot[1] += (
                dt / 10 * _LeadSpeed(t + (i + 0.5) * dt / 10, brake_at, deceleration)
            )
        gaps.append(
            np.linalg.norm(state.positions[0] - robot) - ROBOT_RADIUS - PERSON_RADIUS
        )
    return np.array(gaps)


@pytest.mark.parametrize("people", [_Rvo2Gaps, _CrowdGaps], ids=["rvo2", "crowd"])
def test_a_faster_orca_person_follows_a_robot_at_its_top_speed_within_millimetres(
    people,
):
    gaps = people()
    # It catches up (2 m behind, four times as fast) and follows in touching
    # distance, within 1 cm for the last 5 s, without touching.
    assert gaps[0] > 1.0
    assert np.max(gaps[-len(gaps) // 3 :]) < 0.01
    assert np.min(gaps) > 0.0


@pytest.mark.parametrize("people", [_Rvo2Gaps, _CrowdGaps], ids=["rvo2", "crowd"])
@pytest.mark.parametrize("deceleration", [0.25, 0.5, 1.0])
def test_the_robot_braking_with_an_orca_person_behind_is_a_contact(
    people, deceleration
):
    # The same run with the robot braking at 8 s, after the person has
    # caught up: the person, who left half of the avoidance to the robot,
    # walks into it, even at a gentle 0.25 m/s². RVO2 (0.1 s steps, the
    # robot's velocity of the step before) by 7-23 mm; the studies' people
    # (0.05 s steps, the velocity at the step's start) by 0.5-2 mm, within
    # the depths of the doorway's contacts from behind (0.6-14 mm).
    braking = people(brake_at=8.0, deceleration=deceleration)
    assert np.min(people()) > 0.0
    assert np.min(braking) < 0.0
    assert np.argmin(braking) * (0.1 if people is _Rvo2Gaps else 0.05) > 8.0
