"""Run metrics (summary printed after every run)."""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.humans.robot_view import HumanDistances, WallDistances

# Tolerance for calling a state a limit violation (numerical noise).
_LIMIT_TOL = 1e-6


def LimitViolations(log, robot) -> int:
    """Number of logged samples where q or ν lies outside its limits."""
    if not log.states:
        return 0
    x = np.asarray(log.states)
    n = robot.num_positions
    q, nu = x[:, :n], x[:, n:]
    bad = (
        np.any(q < robot.q_lower - _LIMIT_TOL, axis=1)
        | np.any(q > robot.q_upper + _LIMIT_TOL, axis=1)
        | np.any(nu < robot.nu_lower - _LIMIT_TOL, axis=1)
        | np.any(nu > robot.nu_upper + _LIMIT_TOL, axis=1)
    )
    return int(bad.sum())


# Hall's intimate space: the 0.45 m circle around a human's centre
# (Section V).
INTIMATE_DISTANCE = 0.45


def _SampleDurations(times) -> np.ndarray:
    """How long each sample stands for: the time to the next one (the last
    one the period before it)."""
    times = np.asarray(times, dtype=float)
    return np.diff(
        times, append=times[-1] + (times[-1] - times[-2] if len(times) > 1 else 0.0)
    )


def BaseHumanDistances(robot, states, human_positions) -> np.ndarray:
    """(T, H) distance from each human's centre to the base's disc (radius
    ``robot.model.base_radius``, the footprint people see): centre distance
    minus the disc's radius."""
    x = np.asarray(states, dtype=float)
    P = np.asarray(human_positions, dtype=float)  # (T, H, 2)
    if P.size == 0:
        return np.zeros((len(x), 0))
    d = np.linalg.norm(P - x[:, None, :2], axis=-1)
    return d - robot.model.base_radius


# A contact sample counts as the robot's doing when the robot's own motion
# since the previous sample closed the gap to that person by more than this
# (m): a robot standing still, or backing off, while a person walks into it
# does not count (RobotClosingContacts).
ROBOT_CLOSING_TOLERANCE = 1e-3


def RobotClosingContacts(robot, states, human_positions, gap, dist) -> np.ndarray:
    """(T, H) how far (m) the robot's own motion since the previous sample
    closed the gap to each person it is in contact with (gap < 0), where
    that is more than ROBOT_CLOSING_TOLERANCE; 0 elsewhere.

    The change of the distance between two samples splits exactly into the
    robot's part, d(q_t, p_{t−1}) − d(q_{t−1}, p_{t−1}), and the person's,
    d(q_t, p_t) − d(q_t, p_{t−1}); a contact is the robot's doing when the
    robot's part is below −ROBOT_CLOSING_TOLERANCE. Any robot body counts: an
    arm swept into a person by a turning base is the robot closing in."""
    x = np.asarray(states, dtype=float)
    P = np.asarray(human_positions, dtype=float)
    closing = np.zeros(np.shape(gap))
    if len(x) < 2 or P.size == 0:
        return closing
    robot_moved = HumanDistances(robot, x[1:], P[:-1])  # d(q_t, p_{t−1})
    robot_part = robot_moved - dist[:-1]
    doing = (gap[1:] < 0) & (robot_part < -ROBOT_CLOSING_TOLERANCE)
    closing[1:] = np.where(doing, -robot_part, 0.0)
    return closing


def HumanMetrics(log, robot, human_radii) -> dict:
    """Safety and proxemics against the true human positions.

    Intimate space is the 0.45 m circle around a person's centre (the
    paper's words). ``intimate_space_time_base``: time in which the base's
    disc reaches into anyone's circle (base centre within 0.45 m + base
    radius of a person's centre); ``intimate_space_time``: the same for any
    robot body (base or arm link capsule). ``collision_samples``: samples
    in which any body touches anyone; ``robot_closing_contact_samples``:
    those in which the robot's own motion closed in on the person touched
    (RobotClosingContacts); ``robot_closing_distance``: how far (m) it
    closed in on them, summed over those samples and people."""
    if not log.human_positions:
        return {}
    dist = HumanDistances(robot, log.states, log.human_positions)  # (T, H)
    base = BaseHumanDistances(robot, log.states, log.human_positions)
    radii = np.asarray(human_radii, dtype=float)[None, :]
    gap = dist - radii  # robot surface to human surface
    dt = _SampleDurations(log.times)
    inside = np.any(dist < INTIMATE_DISTANCE, axis=1)
    inside_base = np.any(base < INTIMATE_DISTANCE, axis=1)
    closing = RobotClosingContacts(robot, log.states, log.human_positions, gap, dist)
    return {
        "min_human_distance": float(dist.min()),
        "min_human_gap": float(gap.min()),
        "mean_human_distance": float(dist.mean()),
        "collision_samples": int(np.sum(np.any(gap < 0, axis=1))),
        "robot_closing_contact_samples": int(np.sum(np.any(closing > 0, axis=1))),
        "robot_closing_distance": float(np.sum(closing)),
        "intimate_space_time": float(np.sum(dt[inside])),
        "intimate_space_time_base": float(np.sum(dt[inside_base])),
    }


def SummarizeRun(log, robot, human_radii=None) -> dict:
    """Final and mean task errors, limit violations, solver time, fallbacks,
    and with humans the safety and proxemics figures."""
    out: dict = {"samples": len(log.times)}
    for name, errors in log.task_errors.items():
        norms = np.linalg.norm(np.asarray(errors), axis=1)
        out[f"{name}.final_error"] = float(norms[-1]) if norms.size else float("nan")
        out[f"{name}.mean_error"] = float(norms.mean()) if norms.size else float("nan")
        out[f"{name}.max_error"] = float(norms.max()) if norms.size else float("nan")
    out["limit_violations"] = LimitViolations(log, robot)
    wall = np.array([r.wall_time for r in log.records if r.mode != "none"])
    if wall.size:
        out["step_time_median_ms"] = float(np.median(wall) * 1e3)
        out["step_time_p95_ms"] = float(np.percentile(wall, 95) * 1e3)
        out["step_time_max_ms"] = float(wall.max() * 1e3)
    c = log.counters
    if c is not None:
        out["control_steps"] = c.steps
        out["solver_failures"] = c.solver_failures
        out["fallbacks"] = c.fallbacks
        out["braking_fallbacks"] = c.braking_fallbacks
        out["recovery_steps"] = c.recovery_steps
        out["filtered_steps"] = c.filtered_steps
    if human_radii is not None:
        out.update(HumanMetrics(log, robot, human_radii))
    errors = [
        r.prediction_errors
        for r in log.records
        if getattr(r, "prediction_errors", None) is not None
    ]
    if errors:
        e = np.concatenate(errors)
        out["prediction_consistency"] = float(np.mean(e < 1e-2)) if e.size else 1.0
        out["prediction_error_p95"] = float(np.percentile(e, 95)) if e.size else 0.0
    return out


def FormatMetrics(metrics: dict) -> str:
    width = max(len(k) for k in metrics) if metrics else 0
    lines = []
    for key, value in metrics.items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        lines.append(f"  {key:<{width}}  {text}")
    return "\n".join(lines)


def PolylineDistances(points, polyline) -> np.ndarray:
    """Distance from each 2D point (T, 2) to the polyline (K, 2) (a single
    vertex counts as a point)."""

    P = np.asarray(points, dtype=float).reshape(-1, 2)
    L = np.asarray(polyline, dtype=float).reshape(-1, 2)
    if len(L) == 0:
        raise ValueError("the reference path is empty")
    if len(L) == 1:
        L = np.vstack([L, L])
    d, _, _ = point_segment_distance_2d(L[None, :-1], L[None, 1:], P[:, None, :])
    return d.min(axis=1)


def PathDeviation(base_xy, reference_xy) -> float:
    """Average distance of the base from the optimal path (Section V): the
    mean over the samples of the distance from the base position to the
    reference path (the path the same controller takes with no humans)."""
    return float(PolylineDistances(base_xy, reference_xy).mean())


def Retreat(goal_distances, phases=None) -> float:
    """The largest distance the base gave back on its way to a goal: the
    maximum over t of d(t) − min_{s ≤ t} d(s), where d is the distance to the
    goal; the running minimum restarts when the phase (the goal) changes."""
    d = np.asarray(goal_distances, dtype=float)
    if d.size == 0:
        return float("nan")
    phases = np.zeros(d.size, dtype=int) if phases is None else np.asarray(phases)
    worst, best = 0.0, np.inf
    for i in range(d.size):
        if i and phases[i] != phases[i - 1]:
            best = np.inf
        best = min(best, d[i])
        worst = max(worst, d[i] - best)
    return float(worst)


# The base is "at its goal" within this distance when no phase of the
# task sequence says otherwise (m).
GOAL_TOLERANCE = 0.25
# Freezing: the base within FREEZE_DISTANCE (m) of where it was
# FREEZE_WINDOW (s) earlier, while not at its goal (issue 12).
FREEZE_DISTANCE = 0.05
FREEZE_WINDOW = 2.0
# Progress (the head-on study): samples with a person's centre within
# PROGRESS_RADIUS (m) of the base's centre count; the base progresses when
# it moves toward its goal faster than PROGRESS_SPEED (m/s).
PROGRESS_RADIUS = 2.0
PROGRESS_SPEED = 0.02


def FreezingTime(times, base_xy, at_goal) -> float:
    """Time the base was frozen: a sample is frozen when the base is within
    FREEZE_DISTANCE of its position FREEZE_WINDOW earlier (the latest sample
    at or before that time) and not at its goal; the frozen time is the sum
    of the intervals between consecutive frozen samples. Samples in the
    first FREEZE_WINDOW have no earlier position and are never frozen."""
    t = np.asarray(times, dtype=float)
    p = np.asarray(base_xy, dtype=float).reshape(-1, 2)
    if t.size < 2:
        return 0.0
    earlier = np.searchsorted(t, t - FREEZE_WINDOW + 1e-9, side="right") - 1
    has = (earlier >= 0) & (t - t[0] >= FREEZE_WINDOW - 1e-9)
    moved = np.linalg.norm(p - p[np.maximum(earlier, 0)], axis=1)
    frozen = has & (moved < FREEZE_DISTANCE) & ~np.asarray(at_goal, dtype=bool)
    both = frozen[:-1] & frozen[1:]
    return float(np.sum(np.diff(t)[both]))


def TimeToGoal(times, goal_errors, tolerance=GOAL_TOLERANCE) -> float:
    """The first time the base's distance to its goal is within
    ``tolerance`` (NaN if never)."""
    e = np.asarray(goal_errors, dtype=float)
    hit = np.flatnonzero(e <= tolerance)
    return float(np.asarray(times, dtype=float)[hit[0]]) if hit.size else float("nan")


def ProgressShare(times, base_xy, goal_xy, human_positions, at_goal=None) -> float:
    """Share of the control steps with a person within PROGRESS_RADIUS of
    the base (centre to centre) in which the base moves toward its goal:
    its realized motion to the next sample, projected on the direction to
    the goal, faster than PROGRESS_SPEED. Steps at the goal do not count;
    NaN if no step counts."""
    t = np.asarray(times, dtype=float)
    p = np.asarray(base_xy, dtype=float).reshape(-1, 2)
    g = np.asarray(goal_xy, dtype=float).reshape(-1, 2)
    P = np.asarray(human_positions, dtype=float)
    if t.size < 2 or P.size == 0:
        return float("nan")
    near = np.min(np.linalg.norm(P - p[:, None, :], axis=-1), axis=1)
    to_goal = g - p
    dist = np.linalg.norm(to_goal, axis=1)
    unit = to_goal / np.maximum(dist, 1e-9)[:, None]
    speed = np.sum(np.diff(p, axis=0) * unit[:-1], axis=1) / np.diff(t)
    count = near[:-1] < PROGRESS_RADIUS
    if at_goal is not None:
        count &= ~np.asarray(at_goal, dtype=bool)[:-1]
    if not np.any(count):
        return float("nan")
    return float(np.mean(speed[count] > PROGRESS_SPEED))


def ObstacleClearance(robot, states, segments) -> float:
    """The smallest distance between any robot capsule's surface and any
    wall segment, in the plane (NaN without walls)."""
    if np.asarray(segments).size == 0 or np.asarray(states).size == 0:
        return float("nan")
    return float(WallDistances(robot, states, segments).min())


def _GoalTolerances(scenario, phases, base_task) -> np.ndarray:
    """Per sample, the tolerance within which the base is at its goal: that
    of the latest phase so far whose done_when names the base task (or
    lists nothing), else GOAL_TOLERANCE."""
    tol = []
    for phase in scenario.sequence:
        if not phase.done_when or base_task in phase.done_when:
            tol.append(phase.tolerance)
        else:
            tol.append(tol[-1] if tol else GOAL_TOLERANCE)
    if not tol:
        return np.full(len(phases), GOAL_TOLERANCE)
    idx = np.clip(np.asarray(phases, dtype=int), 0, len(tol) - 1)
    return np.asarray(tol)[idx]


# SummarizeRun figures a campaign row carries over unchanged.
_SUMMARY_COLUMNS = (
    "intimate_space_time_base",
    "intimate_space_time",
    "mean_human_distance",
    "min_human_gap",
    "collision_samples",
    "robot_closing_contact_samples",
    "robot_closing_distance",
    "step_time_median_ms",
    "step_time_p95_ms",
    "step_time_max_ms",
    "control_steps",
    "solver_failures",
    "fallbacks",
    "braking_fallbacks",
    "recovery_steps",
    "prediction_consistency",
)

# The tidy columns of a campaign run, in order (see CampaignRow).
CAMPAIGN_METRICS = [
    "success",
    "navigation_time",
    "time_to_goal",
    "freezing_time",
    "progress_share",
    "ee_error_mean",
    "ee_error_max",
    "base_error_mean",
    "base_error_final",
    "base_path_deviation",
    "base_retreat",
    "min_human_distance",
    "collision",
    "robot_closing_contact",
    "min_obstacle_clearance",
    "wall_collision",
    *_SUMMARY_COLUMNS,
    "simulated_time",
]

# The CAMPAIGN_METRICS that are True/False (NaN when not measured).
BOOLEAN_METRICS = ("success", "collision", "robot_closing_contact", "wall_collision")


def CampaignRow(log, robot, scenario, metrics: dict, reference_xy=None) -> dict:
    """The Section V metrics of one run, under the names CAMPAIGN_METRICS.

    Args:
        log: the RunLog.
        robot: the MobileManipulator.
        scenario: the Scenario that ran.
        metrics: SummarizeRun's output for the run (plus phases_completed /
            sequence_time with a task sequence).
        reference_xy: the optimal base path (T, 2), or None.

    The EE error is that of the highest-priority EE task (ee_position or
    ee_position_in_base), the base error that of the first base_position or
    base_pose task. Navigation time is the completion time of the task
    sequence (NaN when it did not complete: a timeout); success is its
    completion within the time limit. Time to goal is the same with a
    sequence, and without one the first time the base is within
    GOAL_TOLERANCE of its goal (then success: it got there). Freezing
    time, progress share: see FreezingTime, ProgressShare (at the goal: the
    base within the tolerance of the latest phase that waits for the base
    task). Distances to people
    are from a human's centre to the nearest robot body (base or any arm
    link); the gap subtracts the person's radius; ``collision``: a person
    touched; ``robot_closing_contact``: a person touched while the robot's
    own motion closed in on them (RobotClosingContacts), so a contact in
    which only the person moved is ``collision`` alone. Obstacle clearance:
    any robot capsule to any wall; ``wall_collision``: it went below 0.
    """
    nan = float("nan")
    row = dict.fromkeys(CAMPAIGN_METRICS, nan)
    kinds = {t.name or t.kind: t.kind for t in scenario.tasks}
    ee = next((n for n, k in kinds.items() if k.startswith("ee_position")), None)
    base = next((n for n, k in kinds.items() if k.startswith("base_")), None)
    times = np.asarray(log.times, dtype=float)
    phases = np.asarray(log.phases) if log.phases else None
    if ee is not None and log.task_errors.get(ee):
        e = np.linalg.norm(np.asarray(log.task_errors[ee])[:, :3], axis=1)
        row["ee_error_mean"], row["ee_error_max"] = float(e.mean()), float(e.max())
    states = np.asarray(log.states)
    goal_errors = None
    if base is not None and log.task_errors.get(base):
        e_xy = np.asarray(log.task_errors[base])[:, :2]
        goal_errors = e = np.linalg.norm(e_xy, axis=1)
        row["base_error_mean"] = float(e.mean())
        row["base_error_final"] = float(e[-1])
        row["base_retreat"] = Retreat(e, phases)
        at_goal = e <= _GoalTolerances(scenario, log.phases or [0] * e.size, base)
        row["freezing_time"] = FreezingTime(times, states[:, :2], at_goal)
        if log.human_positions:
            # The goal is where the error vanishes: p − e.
            row["progress_share"] = ProgressShare(
                times,
                states[:, :2],
                states[:, :2] - e_xy,
                log.human_positions,
                at_goal,
            )
    if reference_xy is not None and len(states):
        row["base_path_deviation"] = PathDeviation(states[:, :2], reference_xy)
    if scenario.sequence:
        done = metrics.get("phases_completed", 0) == len(scenario.sequence)
        row["success"] = bool(done)
        row["navigation_time"] = float(metrics["sequence_time"]) if done else nan
        row["time_to_goal"] = row["navigation_time"]
    else:
        row["success"] = True
        row["navigation_time"] = float(times[-1]) if times.size else nan
        if goal_errors is not None:
            row["time_to_goal"] = TimeToGoal(times, goal_errors)
            row["success"] = not np.isnan(row["time_to_goal"])
    if scenario.obstacles and len(states):
        clearance = ObstacleClearance(
            robot, states, ObstacleSegments(scenario.obstacles)
        )
        row["min_obstacle_clearance"] = clearance
        row["wall_collision"] = bool(clearance < 0.0)
    if "min_human_distance" in metrics:  # HumanMetrics measured it
        row["min_human_distance"] = metrics["min_human_distance"]
    elif log.human_positions:
        dist = HumanDistances(robot, log.states, log.human_positions)
        row["min_human_distance"] = float(dist.min())
    for key in _SUMMARY_COLUMNS:
        if key in metrics:
            row[key] = metrics[key]
    if "collision_samples" in metrics:
        row["collision"] = bool(metrics["collision_samples"] > 0)
    if "robot_closing_contact_samples" in metrics:
        row["robot_closing_contact"] = bool(
            metrics["robot_closing_contact_samples"] > 0
        )
    row["simulated_time"] = float(times[-1]) if times.size else 0.0
    return row
