"""The ``instructed`` person (humans/crowd.py): told to walk a fixed path, it
ignores the robot until the robot comes within its reaction distance, then
avoids it late, taking the whole avoidance itself.

Its path is the polyline start → waypoints. While on it, the person walks
straight to its current waypoint. Off it (after stepping aside for the
robot) it walks back onto it, aiming ``PATH_LOOKAHEAD`` ahead along the
leg, as someone told to follow a route does; heading straight for the
waypoint instead can cut through a wall (a door's jamb) or pin the person in
the corner beside a door, where its velocity toward the waypoint points
into the wall. Walls are always kept (RVO2's obstacle lines), and so are
the other people: instructed people are told a route, not to walk through
each other, so they avoid one another as the crowd does (reciprocal ORCA
over the crowd's τ). Without that, in the doorway with 3 people they
overlapped in all 10 runs checked (up to 0.6 m deep, for 11–76 % of a
run), a scene
no sensor reports and SM²ITH's model of people avoiding one another
misreads.
"""

import numpy as np

from sm2ith_drake.humans.orca_velocity import orca_velocity
from sm2ith_drake.humans.robot_view import RobotAgents, RobotGap

# When the robot is in its way, the person aims this much to its right
# (rad), so that a head-on meeting is resolved to one side,
# deterministically ...
KEEP_RIGHT_ANGLE = np.radians(30.0)
# ... and passes the robot with this much room (m): it avoids the robot's
# bodies inflated by it, not by a hair's breadth.
INSTRUCTED_CLEARANCE = 0.1
# Farther than this from its path's current leg (m), the person walks back
# onto it, aiming PATH_LOOKAHEAD ahead along the leg (m). Above crowd.py's
# WAYPOINT_TOLERANCE (0.2 m), so a person who turns at a waypoint it has come
# within that distance of is on its new leg, as a scripted person.
PATH_TOLERANCE = 0.25
PATH_LOOKAHEAD = 1.0
# The person keeps right only for a robot ahead: its base within this angle
# of the path's direction (rad). A robot to the side (a person pinned
# beside a door jamb, the robot a metre off to one side of the door) is left
# to ORCA: stepping right there turned the person into the wall, for good.
HEAD_ON_ANGLE = np.radians(45.0)


def _HeadOn(position, path_v, robot_position) -> bool:
    """Whether the robot's base is ahead along ``path_v`` (HEAD_ON_ANGLE)."""
    to_robot = np.asarray(robot_position, dtype=float)[:2] - position
    dist, speed = np.linalg.norm(to_robot), np.linalg.norm(path_v)
    if dist < 1e-9 or speed < 1e-12:
        return True
    return float(to_robot @ path_v) >= np.cos(HEAD_ON_ANGLE) * dist * speed


def PathVelocity(position, v_pref, leg_start, goal):
    """The velocity of a person following the leg ``leg_start`` → ``goal``
    at ``v_pref``'s speed: ``v_pref`` itself (straight to the waypoint)
    within PATH_TOLERANCE of the leg, else toward the point PATH_LOOKAHEAD
    beyond its projection on the leg (clamped to the goal)."""
    a = np.asarray(leg_start, dtype=float)
    g = np.asarray(goal, dtype=float)
    d = g - a
    length = float(np.linalg.norm(d))
    speed = float(np.linalg.norm(v_pref))
    if length < 1e-9 or speed < 1e-12:
        return v_pref
    along = float(np.clip(np.dot(position - a, d) / length, 0.0, length))
    foot = a + along / length * d
    if np.linalg.norm(position - foot) <= PATH_TOLERANCE:
        return v_pref
    aim = a + min(along + PATH_LOOKAHEAD, length) / length * d
    to_aim = aim - position
    dist = float(np.linalg.norm(to_aim))
    return v_pref if dist < 1e-9 else to_aim / dist * speed


def InstructedVelocity(
    h,
    position,
    velocity,
    v_pref,
    *,
    leg_start,
    goal,
    robot_position,
    robot_velocity,
    robot_radius,
    robot_bodies,
    obstacle_segments,
    tau_obs,
    dt,
    others=None,
    tau=2.0,
):
    """An instructed person's velocity. Its path's velocity (PathVelocity;
    ``v_pref`` on the path), kept off the walls, while the robot is farther
    than its reaction distance; else the velocity closest to it that keeps
    clear of the robot alone (its bodies inflated by INSTRUCTED_CLEARANCE)
    and the walls, the person taking all of the avoidance (share 1: it does
    not count on the robot), for as long as it takes the person to walk its
    reaction distance (1 m at 1 m/s: 1 s, half the crowd's τ). ``others``
    (positions (M, 2), velocities (M, 2), radii (M,)): the other people,
    avoided reciprocally over ``tau`` (the crowd's) in either case."""
    walls = [tuple(s) for s in obstacle_segments]
    speed = max(h.speed, 1e-3)
    path_v = PathVelocity(position, v_pref, leg_start, goal)
    gap = RobotGap(position, h.radius, robot_position, robot_radius, robot_bodies)
    people_p, people_v, people_r = (
        (np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)) if others is None else others
    )
    people = len(people_p)

    def Unhindered(preferred):
        # The walls and the other people alone.
        if not walls and not people:
            return preferred
        return orca_velocity(
            position,
            velocity,
            h.radius,
            people_p,
            people_v,
            people_r,
            preferred_velocity=preferred,
            max_speed=speed,
            tau=tau,
            tau_obs=tau_obs,
            time_step=dt,
            obstacles=walls,
        )

    if gap >= h.reaction_distance:
        return Unhindered(path_v)
    robot_p, robot_r = RobotAgents(position, robot_position, robot_radius, robot_bodies)
    robots = len(robot_p)
    reaction_time = h.reaction_distance / speed

    def Avoid(preferred):
        # The robot alone late, taking it all; the others as the crowd does.
        return orca_velocity(
            position,
            velocity,
            h.radius,
            np.vstack([robot_p, people_p]),
            np.vstack([np.tile(robot_velocity, (robots, 1)), people_v]),
            np.concatenate([robot_r + INSTRUCTED_CLEARANCE, people_r]),
            preferred_velocity=preferred,
            max_speed=speed,
            tau=np.r_[np.full(robots, reaction_time), np.full(people, tau)],
            tau_obs=tau_obs,
            time_step=dt,
            shares=np.r_[np.ones(robots), np.full(people, 0.5)],
            obstacles=walls,
        )

    new_v = Avoid(path_v)
    if not _HeadOn(position, path_v, robot_position) or np.allclose(
        new_v, Unhindered(path_v), rtol=0.0, atol=1e-9
    ):
        # Not ahead, or ahead but not in the way (what changes the path's
        # velocity is a wall or another person): ORCA's avoidance as it is.
        return new_v
    # Ahead and in the way: the person steps aside to its right. Head-on,
    # ORCA alone would have it stop dead in front of the robot (the
    # symmetric case).
    c, s = np.cos(KEEP_RIGHT_ANGLE), np.sin(KEEP_RIGHT_ANGLE)
    return Avoid(np.array([[c, s], [-s, c]]) @ path_v)
