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
  the model" of the safety tests;
- ``instructed``: a person told to walk a fixed path (the paper's
  participants): it walks its waypoints at its speed like ``scripted``,
  ignoring the robot (not the other people, whom it avoids as the crowd
  does: nobody is told to walk through others) until the robot (its
  nearest body, or the base disc) comes within ``reaction_distance`` of the
  person's surface.
  Then it avoids the robot late: each step, the velocity closest to its
  path's that keeps clear of the robot alone for a short horizon (RVO2's
  velocity selection with the robot's base and nearest body as agents,
  inflated by ``INSTRUCTED_CLEARANCE``, over the time it takes the person
  to walk its reaction distance, the person taking the whole avoidance, the
  walls kept); when the robot is in its way
  it steps to its right (``KEEP_RIGHT_ANGLE``), so a head-on meeting does not
  end in a stand-off. Off its path it walks back onto it (not straight to
  the waypoint, which can cut a door's jamb), and it keeps off the walls
  (humans/instructed.py). It never uses the prediction's model: one of the
  people who do not behave as SM²ITH assumes.

Any person with a ``start_phase`` stands at its start until the robot's task
sequence enters that phase; its ``start_time`` then counts from that moment
(the crowd notices the phase at its first step in it). Likewise a waypoint
gated by ``waypoint_phases`` is walked to only once the sequence has entered
its phase: until then the person keeps to its previous waypoint (or start).
When each phase was entered is part of the CrowdState, so a cloned Context
reproduces the run.
"""

from dataclasses import dataclass

import numpy as np

from sm2ith_drake.humans.half_planes import obstacle_half_planes, orca_agent_half_planes
from sm2ith_drake.humans.instructed import InstructedVelocity
from sm2ith_drake.humans.orca_velocity import orca_velocity
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_action
from sm2ith_drake.humans.robot_view import (
    NearestBodyOnFloor,
    NearestRobotPoint,
    RobotAgents,
    RobotGap,
)
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
    # (H,) when each person's ``start_phase`` was entered (NaN: not yet, or
    # the person has none).
    phase_entered: np.ndarray | None = None
    # (H, W) when the phase gating each person's waypoint k was entered
    # (NaN: not yet, or no gate); W: the most waypoints anyone has.
    gate_entered: np.ndarray | None = None


def InitialCrowdState(humans) -> CrowdState:
    H = len(humans)
    return CrowdState(
        positions=np.array([h.start for h in humans], dtype=float).reshape(H, 2),
        velocities=np.zeros((H, 2)),
        waypoint=np.zeros(H, dtype=int),
        preferred=np.full((H, 2), np.nan),
        phase_entered=np.full(H, np.nan),
        gate_entered=np.full(_GateNames(humans).shape, np.nan),
    )


def _GateNames(humans) -> np.ndarray:
    """(H, W) the phase gating each person's waypoint k ("": none)."""
    W = max([len(h.waypoints) for h in humans], default=0)
    names = np.full((len(humans), W), "", dtype=object)
    for j, h in enumerate(humans):
        names[j, : len(h.waypoint_phases)] = h.waypoint_phases
    return names


def EnterPhases(names, entered, *, phases, phase_index, time: float):
    """``entered`` (the times the phases ``names`` were entered, NaN: not
    yet; any shape, "" for no phase) updated at ``time``: a phase counts as
    entered once the sequence's ``phase_index`` (``len(phases)`` once
    finished; None: unknown) has reached the phase's first occurrence in
    ``phases``, the sequence's phase names, so a phase shorter than a crowd
    step is not missed. Once entered stays entered."""
    entered = np.array(entered, dtype=float)
    if phase_index is None:
        return entered
    names = np.asarray(names, dtype=object).reshape(entered.shape)
    for k in np.ndindex(entered.shape):
        if names[k] and np.isnan(entered[k]):
            if phase_index >= list(phases).index(names[k]):
                entered[k] = time
    return entered


def StartTimes(humans, phase_entered) -> np.ndarray:
    """(H,) when each person starts walking (s): its ``start_time``, counted
    from the entering of its start phase if it has one (inf until then)."""
    starts = np.array([h.start_time for h in humans], dtype=float)
    for j, h in enumerate(humans):
        if h.start_phase:
            t0 = phase_entered[j]
            starts[j] = np.inf if np.isnan(t0) else t0 + h.start_time
    return starts


def PreferredVelocities(
    humans, state: CrowdState, time: float, start_times=None, gate_entered=None
):
    """Velocity toward each human's current waypoint (advancing past reached
    waypoints), at its speed, slowing down over the last metre; zero before
    the person's start time (``start_times``, default: its ``start_time``).
    A waypoint whose gate is not yet entered (``gate_entered``, default:
    the state's) is not walked to: the person keeps to the one before it
    (or its start)."""
    H = len(humans)
    v_pref = np.zeros((H, 2))
    goals = state.positions.copy()
    if start_times is None:
        start_times = [h.start_time for h in humans]
    if gate_entered is None:
        gate_entered = state.gate_entered
    for j, h in enumerate(humans):
        if not h.waypoints or time < start_times[j]:
            continue
        w = state.waypoint[j]
        goal = np.asarray(h.waypoints[w % len(h.waypoints)], dtype=float)
        if np.linalg.norm(goal - state.positions[j]) < WAYPOINT_TOLERANCE:
            if h.loop or w + 1 < len(h.waypoints):
                w = state.waypoint[j] = w + 1
                goal = np.asarray(h.waypoints[w % len(h.waypoints)], dtype=float)
        # Gated waypoints are never looped (scenario_checks.py).
        if w < len(h.waypoint_phases) and h.waypoint_phases[w]:
            if np.isnan(gate_entered[j, w]):
                goal = np.asarray(h.waypoints[w - 1] if w else h.start, dtype=float)
        goals[j] = goal
        d = goal - state.positions[j]
        dist = np.linalg.norm(d)
        if dist > 1e-9:
            v_pref[j] = d / dist * h.speed * min(1.0, dist)
    return v_pref, goals


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
    phases=(),
    phase_index=None,
) -> CrowdState:
    """Advances every human by dt; returns the new state.

    ``robot_bodies`` = (segments (C, 2, 2), radii (C,)): the robot's capsules
    projected on the floor (default: the base disc). ``model``: the
    PredictionConfig whose relaxed-ORCA model the "relaxed_orca" people
    follow. ``phases``: the names of the robot's task sequence;
    ``phase_index``: the phase it is in (``len(phases)`` once finished;
    None: unknown, so nobody with a ``start_phase`` starts and no gated
    waypoint opens)."""
    H = len(humans)
    p, v = state.positions.copy(), state.velocities.copy()
    radii = np.array([h.radius for h in humans], dtype=float)
    names = _GateNames(humans)
    entered, gates = state.phase_entered, state.gate_entered
    if entered is None:
        entered = np.full(H, np.nan)
    if gates is None:
        gates = np.full(names.shape, np.nan)
    when = dict(phases=phases, phase_index=phase_index, time=time)
    entered = EnterPhases([h.start_phase for h in humans], entered, **when)
    gates = EnterPhases(names, gates, **when)
    start_times = StartTimes(humans, entered)
    v_pref, goals = PreferredVelocities(humans, state, time, start_times, gates)
    robot_position = np.asarray(robot_position, dtype=float)[:2]
    robot_velocity = np.asarray(robot_velocity, dtype=float)[:2]
    new_v = np.zeros((H, 2))
    preferred = np.full((H, 2), np.nan)
    social = [j for j, h in enumerate(humans) if h.behavior == "social_force"]
    for j, h in enumerate(humans):
        waiting = time < start_times[j]
        others = [i for i in range(H) if i != j]
        if h.behavior == "instructed":
            w = state.waypoint[j]
            new_v[j] = InstructedVelocity(
                h,
                p[j],
                v[j],
                v_pref[j],
                leg_start=h.waypoints[(w - 1) % len(h.waypoints)] if w else h.start,
                goal=goals[j],
                robot_position=robot_position,
                robot_velocity=robot_velocity,
                robot_radius=robot_radius,
                robot_bodies=robot_bodies,
                obstacle_segments=obstacle_segments,
                tau_obs=tau_obs,
                dt=dt,
                others=(p[others], v[others], radii[others]),
                tau=tau,
            )
        elif h.behavior == "scripted" or (waiting and h.behavior != "orca"):
            new_v[j] = v_pref[j]
        elif h.behavior == "adversarial":
            d = robot_position - p[j]
            gap = RobotGap(p[j], h.radius, robot_position, robot_radius, robot_bodies)
            if waiting or gap <= ADVERSARY_STOP_GAP:
                new_v[j] = 0.0
            else:
                step = min(h.speed, (gap - ADVERSARY_STOP_GAP) / dt)
                new_v[j] = d / np.linalg.norm(d) * step
        elif h.behavior == "orca":
            robot_p, robot_r = RobotAgents(
                p[j], robot_position, robot_radius, robot_bodies
            )
            new_v[j] = orca_velocity(
                p[j],
                v[j],
                h.radius,
                np.vstack([p[others], robot_p]),
                np.vstack([v[others], np.tile(robot_velocity, (len(robot_p), 1))]),
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
        # Everyone moves in the model (the social-force people are pushed by
        # all the others and the robot's point nearest to them); only their
        # own rows are kept.
        robot = (robot_position, robot_radius, robot_bodies)
        nearest = [NearestRobotPoint(p[j], *robot) for j in range(H)]
        _, sv = social_force_step(
            p,
            v,
            goals,
            radii,
            dt=dt,
            robot_points=np.array([point for point, _ in nearest]),
            robot_point_radii=np.array([r for _, r in nearest]),
            obstacles=[tuple(s) for s in obstacle_segments],
            max_speeds=np.array([max(h.speed, 1e-3) for h in humans]),
        )
        new_v[social] = sv[social]
    return CrowdState(
        positions=p + dt * new_v,
        velocities=new_v,
        waypoint=state.waypoint.copy(),
        preferred=preferred,
        phase_entered=entered,
        gate_entered=gates,
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
        body_p, body_r, _ = NearestBodyOnFloor(p[j], robot_bodies)
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
