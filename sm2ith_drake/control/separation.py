"""Speed-and-separation monitoring of the base's turn (SafetyConfig.
turn_monitoring; not in the paper, the `safe` variant only, every method
alike).

A base that turns sweeps every body on it, the arm's farthest, at ω·r. The
DT-CBF bounds how fast a body approaches a person at each knot, not how
fast it moves past them; a Stretch 3 turning in place at its top rate (1
rad/s, 1.5 rad/s² to stop: 0.33 rad of further turn) with its gripper out
sweeps 0.2 m before it can stop, twice the barrier's margin. Traced in the
studies (README, Contact in the `safe` variant): with a person 8–17 cm from
its body the plan kept turning at 1 rad/s and paid barrier slack through
the contact, as the turn could no longer be stopped in time.

The rule, as in ISO/TS 15066's speed and separation monitoring: a turn
must be one that stops before any body reaches a person's margin, taking
the farthest body as the one that sweeps toward them. With h the smallest
barrier value over the robot's bodies and the tracked people at the
measured state (surface to surface, less the margin), α the yaw
deceleration limit and r the distance from the base's centre to the
farthest point of any body,

    r·ω²/(2α) ≤ h   ⇔   |ω| ≤ √(2αh/r),

never below ``turn_speed_floor`` (so a robot with someone at its margin can
still turn, slowly). It bounds ω at the knots within the yaw's stopping
time, each no tighter than braking from the measured ω allows (the bounds
stay feasible: ν_0 is pinned to the measured velocity).
"""

import math

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.robots.planar_base import NumBaseVelocities


def TurnLimits(
    robot,
    q0: np.ndarray,
    nu0: np.ndarray,
    people: np.ndarray,
    *,
    human_radius: float,
    human_margin: float,
    floor: float,
    time_step: float,
    horizon: int,
) -> tuple[int, np.ndarray] | None:
    """The yaw rate's bounds (module doc): (the ν index of the yaw rate,
    |ω| bounds for knots 1 … K), or None where nothing binds (nobody
    tracked, or the rule allows the top rate). ``people`` (P, 2): the
    tracked people's measured positions."""
    people = np.asarray(people, dtype=float).reshape(-1, 2)
    people = people[np.all(np.isfinite(people), axis=1)]
    q0 = np.asarray(q0, dtype=float)
    if people.size == 0 or not np.all(np.isfinite(q0)):
        return None
    w = NumBaseVelocities(robot) - 1
    top = min(-robot.nu_lower[w], robot.nu_upper[w])
    alpha = min(-robot.nudot_lower[w], robot.nudot_upper[w])
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]  # (C, 2, 2)
    radii = robot.capsule_radii
    d, _, _ = point_segment_distance_2d(
        ends[None, :, 0], ends[None, :, 1], people[:, None, :]
    )  # (P, C)
    h = float(np.min(d - radii[None] - human_radius - human_margin))
    reach = np.linalg.norm(ends - q0[None, None, :2], axis=2) + radii[:, None]
    r = float(np.max(reach))
    limit = max(float(floor), math.sqrt(2.0 * alpha * max(h, 0.0) / max(r, 1e-6)))
    if limit >= top:
        return None
    # The knots within the yaw's stopping time from its top rate.
    steps = min(int(horizon), math.ceil(top / alpha / time_step - 1e-9))
    k = np.arange(1, steps + 1)
    omega0 = abs(float(nu0[w])) if np.isfinite(nu0[w]) else top
    bounds = np.maximum(limit, omega0 - alpha * time_step * k)
    return w, np.minimum(bounds, top)
