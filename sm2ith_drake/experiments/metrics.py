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


def SummarizeRun(log, robot) -> dict:
    """Final and mean task errors, limit violations, solver time, fallbacks."""
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
    return out


def FormatMetrics(metrics: dict) -> str:
    width = max(len(k) for k in metrics) if metrics else 0
    lines = []
    for key, value in metrics.items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        lines.append(f"  {key:<{width}}  {text}")
    return "\n".join(lines)
