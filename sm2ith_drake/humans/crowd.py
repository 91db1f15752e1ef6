"""Behaviour models of the simulated people (plain numpy, one step at a time).

The crowd moves with time step Δt_c. Each human has a behaviour:

- ``orca``: the velocity RVO2's ORCA would choose (van den Berg et al. 2011)
  toward its current waypoint, with the other humans and the robot (its base
  and its body nearest to the person, e.g. an outstretched arm) as agents and
  the static obstacles as lines;
- ``social_force``: Helbing's social force model, so a predictor is not only
  scored against its own model;
- ``scripted``: walks its waypoints at its speed, ignoring everyone;
- ``adversarial``: walks straight at the robot base, stopping 10 cm before
  touching any robot body (base or arm), as a person blocking the robot
  would;
- ``relaxed_orca``: walks its waypoints exactly as SM²ITH's prediction model
  says a person does: the relaxed-ORCA QP (eq. relaxed_orca_acc_argmin) with
  the prediction's parameters, the crowd's step as Δt, the other people and
  the robot's base and nearest body as agents and one line per wall
  (humans/orca_kkt.py). With ideal perception the controller also knows
  their preferred velocities, so these are the people who "behave within
  the model" of the safety tests.
"""

from dataclasses import dataclass

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.humans.half_planes import obstacle_half_planes, orca_agent_half_planes
from sm2ith_drake.humans.orca_velocity import orca_velocity
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_action
from sm2ith_drake.humans.social_force import social_force_step

# A waypoint counts as reached within this distance (m).
WAYPOINT_TOLERANCE = 0.2
# An adversarial person stops this far from the robot's bodies (m).
ADVERSARY_STOP_GAP = 0.1


@dataclass
class CrowdState:
    positions: np.ndarray  # (H, 2)
    velocities: np.ndarray  # (H, 2)
    waypoint: np.ndarray  # (H,) index of the current goal
    # The preferred velocity each "relaxed_orca" person used in its last
    # step (NaN for the other behaviours): their intent, as ground truth.
    preferred: np.ndarray | None = None


def InitialCrowdState(humans) -> CrowdState:
    H = len(humans)
    return CrowdState(
        positions=np.array([h.start for h in humans], dtype=float).reshape(H, 2),
        velocities=np.zeros((H, 2)),
        waypoint=np.zeros(H, dtype=int),
        preferred=np.full((H, 2), np.nan),
    )


def PreferredVelocities(humans, state: CrowdState, time: float):
    """Velocity toward each human's current waypoint (advancing past reached
    waypoints), at its speed, slowing down over the last metre."""
    H = len(humans)
    v_pref = np.zeros((H, 2))
    goals = state.positions.copy()
    for j, h in enumerate(humans):
        if not h.waypoints or time < h.start_time:
            continue
        w = state.waypoint[j]
        goal = np.asarray(h.waypoints[w % len(h.waypoints)], dtype=float)
        if np.linalg.norm(goal - state.positions[j]) < WAYPOINT_TOLERANCE:
            if h.loop or w + 1 < len(h.waypoints):
                state.waypoint[j] = w + 1
                goal = np.asarray(h.waypoints[(w + 1) % len(h.waypoints)], dtype=float)
        goals[j] = goal
        d = goal - state.positions[j]
        dist = np.linalg.norm(d)
        if dist > 1e-9:
            v_pref[j] = d / dist * h.speed * min(1.0, dist)
    return v_pref, goals


def _NearestBody(position, robot_bodies):
    """The robot capsule nearest to ``position`` on the floor: (the closest
    point on its axis, its radius, its surface distance)."""
    segments, radii = robot_bodies
    a, b = segments[:, 0], segments[:, 1]
    d, s, _ = point_segment_distance_2d(a, b, position)
    closest = a + s[:, None] * (b - a)
    d = d - radii
    i = int(np.argmin(d))
    return closest[i], float(radii[i]), float(d[i])


def _Gap(position, radius, robot_position, robot_radius, robot_bodies):
    """Clearance between a person and the nearest robot body (m)."""
    gap = np.linalg.norm(robot_position - position) - robot_radius - radius
    if robot_bodies is not None:
        gap = min(gap, _NearestBody(position, robot_bodies)[2] - radius)
    return gap


def StepCrowd(
    humans,
    state: CrowdState,
    *,
    time: float,
    dt: float,
    robot_position,
    robot_velocity,
    robot_radius: float,
    obstacle_segments,
    tau: float,
    tau_obs: float,
    robot_bodies=None,
    model=None,
) -> CrowdState:
    """Advances every human by dt; returns the new state.

    ``robot_bodies`` = (segments (C, 2, 2), radii (C,)): the robot's capsules
    projected on the floor (default: the base disc). ``model``: the
    PredictionConfig whose relaxed-ORCA model the "relaxed_orca" people
    follow."""
    H = len(humans)
    p, v = state.positions.copy(), state.velocities.copy()
    radii = np.array([h.radius for h in humans], dtype=float)
    v_pref, goals = PreferredVelocities(humans, state, time)
    robot_position = np.asarray(robot_position, dtype=float)[:2]
    robot_velocity = np.asarray(robot_velocity, dtype=float)[:2]
    new_v = np.zeros((H, 2))
    preferred = np.full((H, 2), np.nan)
    social = [j for j, h in enumerate(humans) if h.behavior == "social_force"]
    for j, h in enumerate(humans):
        waiting = time < h.start_time
        if h.behavior == "scripted" or (waiting and h.behavior != "orca"):
            new_v[j] = v_pref[j]
        elif h.behavior == "adversarial":
            d = robot_position - p[j]
            gap = _Gap(p[j], h.radius, robot_position, robot_radius, robot_bodies)
            if waiting or gap <= ADVERSARY_STOP_GAP:
                new_v[j] = 0.0
            else:
                step = min(h.speed, (gap - ADVERSARY_STOP_GAP) / dt)
                new_v[j] = d / np.linalg.norm(d) * step
        elif h.behavior == "orca":
            others = [i for i in range(H) if i != j]
            # The robot as people see it: its base and, as a second agent,
            # the nearest of its bodies (an arm sticking out is avoided too),
            # moving with the base.
            robot_p, robot_r = [robot_position], [robot_radius]
            if robot_bodies is not None:
                point, r, _ = _NearestBody(p[j], robot_bodies)
                if np.linalg.norm(point - robot_position) > 1e-6:
                    robot_p.append(point)
                    robot_r.append(r)
            new_v[j] = orca_velocity(
                p[j],
                v[j],
                h.radius,
                np.vstack([p[others], *robot_p]),
                np.vstack([v[others], *([robot_velocity] * len(robot_p))]),
                np.concatenate([radii[others], robot_r]),
                preferred_velocity=v_pref[j],
                max_speed=max(h.speed, 1e-3),
                tau=tau,
                tau_obs=tau_obs,
                time_step=dt,
                obstacles=[tuple(s) for s in obstacle_segments],
            )
        elif h.behavior == "relaxed_orca":
            if model is None:
                raise ValueError("relaxed_orca people need the prediction model")
            new_v[j] = _ModelVelocity(
                j,
                p,
                v,
                radii,
                v_pref[j],
                robot_position=robot_position,
                robot_velocity=robot_velocity,
                robot_radius=robot_radius,
                robot_bodies=robot_bodies,
                obstacle_segments=obstacle_segments,
                model=model,
                dt=dt,
            )
            preferred[j] = v_pref[j]
    if social:
        # Everyone moves in the model (so the social-force people are pushed
        # by all the others); only their own rows are kept.
        _, sv = social_force_step(
            p,
            v,
            goals,
            radii,
            dt=dt,
            robot_position=robot_position,
            robot_velocity=robot_velocity,
            robot_radius=robot_radius,
            obstacles=[tuple(s) for s in obstacle_segments],
            max_speeds=np.array([max(h.speed, 1e-3) for h in humans]),
        )
        new_v[social] = sv[social]
    return CrowdState(
        positions=p + dt * new_v,
        velocities=new_v,
        waypoint=state.waypoint.copy(),
        preferred=preferred,
    )


def _ModelVelocity(
    j,
    p,
    v,
    radii,
    v_pref,
    *,
    robot_position,
    robot_velocity,
    robot_radius,
    robot_bodies,
    obstacle_segments,
    model,
    dt,
):
    """Person j's next velocity by the prediction model (humans/orca_kkt.py):
    the relaxed-ORCA QP over the other people's, the robot base's and the
    robot's nearest body's ORCA lines and one line per wall."""

    others = [i for i in range(len(p)) if i != j]
    if robot_bodies is None:
        body_p, body_r = robot_position, robot_radius
    else:
        body_p, body_r, _ = _NearestBody(p[j], robot_bodies)
    other_p = np.vstack([p[others], robot_position, body_p])
    other_v = np.vstack([v[others], robot_velocity, robot_velocity])
    radius = np.concatenate([radii[others], [robot_radius, body_r]]) + radii[j]
    share = np.concatenate([np.full(len(others), 0.5), [model.robot_share] * 2])
    n, rho = orca_agent_half_planes(
        p[j], v[j], other_p, other_v, radius, share, tau=model.tau, time_step=dt
    )
    segments = np.asarray(obstacle_segments, dtype=float).reshape(-1, 2, 2)
    no, rho_o = obstacle_half_planes(p[j], segments, radii[j], tau_obs=model.tau_obs)
    return relaxed_orca_action(
        v_pref,
        v[j],
        n,
        rho,
        max_speed=model.max_speed,
        max_accel=model.max_acceleration,
        time_step=dt,
        slack_weights=(model.slack_weight_acceleration, model.slack_weight_velocity),
        static_normals=no,
        static_offsets=rho_o,
    ).velocity
