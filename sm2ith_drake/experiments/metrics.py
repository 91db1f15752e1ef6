"""Run metrics (summary printed after every run)."""

from __future__ import annotations

import numpy as np

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


def HumanDistances(robot, states, human_positions) -> np.ndarray:
    """(T, H) horizontal distance from each human's centre to the nearest
    robot body (every capsule's surface: the base and every arm link)."""
    from sm2ith_drake.control.cbf import point_segment_distance_2d

    x = np.asarray(states)
    P = np.asarray(human_positions, dtype=float)  # (T, H, 2)
    if P.size == 0:
        return np.zeros((len(x), 0))
    kin = robot.CalcKinematics(x[:, : robot.num_positions])
    ends = kin.capsule_points[..., :2]  # (T, C, 2, 2)
    d, _, _ = point_segment_distance_2d(
        ends[:, None, :, 0], ends[:, None, :, 1], P[:, :, None, :]
    )  # (T, H, C)
    return np.min(d - robot.capsule_radii[None, None, :], axis=2)


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
