"""Run metrics (summary printed after every run)."""

from __future__ import annotations

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.humans.robot_view import HumanDistances

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


# Hall's intimate space: 0.45 m from a human's centre (Section V).
INTIMATE_DISTANCE = 0.45


def HumanMetrics(log, robot, human_radii) -> dict:
    """Safety and proxemics against the true human positions."""
    if not log.human_positions:
        return {}
    dist = HumanDistances(robot, log.states, log.human_positions)  # (T, H)
    radii = np.asarray(human_radii, dtype=float)[None, :]
    gap = dist - radii  # robot surface to human surface
    times = np.asarray(log.times)
    dt = np.diff(
        times, append=times[-1] + (times[-1] - times[-2] if len(times) > 1 else 0.0)
    )
    inside = np.any(dist < INTIMATE_DISTANCE, axis=1)
    return {
        "min_human_gap": float(gap.min()),
        "mean_human_distance": float(dist.mean()),
        "collision_samples": int(np.sum(np.any(gap < 0, axis=1))),
        "intimate_space_time": float(np.sum(dt[inside])),
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


# SummarizeRun figures a campaign row carries over unchanged.
_SUMMARY_COLUMNS = (
    "intimate_space_time",
    "mean_human_distance",
    "min_human_gap",
    "collision_samples",
    "step_time_median_ms",
    "step_time_p95_ms",
    "step_time_max_ms",
    "control_steps",
    "solver_failures",
    "fallbacks",
    "braking_fallbacks",
    "prediction_consistency",
)

# The tidy columns of a campaign run, in order (see CampaignRow).
CAMPAIGN_METRICS = [
    "success",
    "navigation_time",
    "ee_error_mean",
    "ee_error_max",
    "base_error_mean",
    "base_error_final",
    "base_path_deviation",
    "base_retreat",
    "min_human_distance",
    "collision",
    *_SUMMARY_COLUMNS,
    "simulated_time",
]


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
    sequence (NaN when it did not complete: a timeout). Distances to people
    are from a human's centre to the nearest robot body (base or any arm
    link); the gap subtracts the person's radius.
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
    if base is not None and log.task_errors.get(base):
        e = np.linalg.norm(np.asarray(log.task_errors[base])[:, :2], axis=1)
        row["base_error_mean"] = float(e.mean())
        row["base_error_final"] = float(e[-1])
        row["base_retreat"] = Retreat(e, phases)
    states = np.asarray(log.states)
    if reference_xy is not None and len(states):
        row["base_path_deviation"] = PathDeviation(states[:, :2], reference_xy)
    if scenario.sequence:
        done = metrics.get("phases_completed", 0) == len(scenario.sequence)
        row["success"] = bool(done)
        row["navigation_time"] = float(metrics["sequence_time"]) if done else nan
    else:
        row["success"] = True
        row["navigation_time"] = float(times[-1]) if times.size else nan
    if log.human_positions:
        dist = HumanDistances(robot, log.states, log.human_positions)
        row["min_human_distance"] = float(dist.min())
    for key in _SUMMARY_COLUMNS:
        if key in metrics:
            row[key] = metrics[key]
    if "collision_samples" in metrics:
        row["collision"] = bool(metrics["collision_samples"] > 0)
    row["simulated_time"] = float(times[-1]) if times.size else 0.0
    return row
