"""Speed-and-separation monitoring of the base's turn (SafetyConfig.
turn_monitoring; not in the paper, the `safe` variant only, every method
alike).

A base that turns sweeps every body on it, the arm's farthest, at ω·r. The
DT-CBF bounds how fast a body approaches a person at each knot, not how
fast it moves past them; a Stretch 3 turning in place at its top rate (1
rad/s, 1.5 rad/s² to stop: 0.33 rad of further turn) with its gripper out
sweeps up to 0.2 m before it can stop, twice the barrier's margin. Traced
in the studies (README, Contact in the `safe` variant): with a person 8–17
cm from its body the plan kept turning at 1 rad/s and paid barrier slack
through the contact, as the turn could no longer be stopped in time.

The rule, as in ISO/TS 15066's speed and separation monitoring: a turn
must be one that can stop before any body reaches a person's margin. For
each direction of turn, the robot's bodies at the measured configuration
are turned about the base's centre through the angles braking from the top
rate would cover (θ_max = ω_max²/(2α), α the yaw deceleration limit), and
θ is the last sampled angle before the barrier h (the smallest over bodies
and tracked people, surface to surface less the margin) falls below
min(h_0, 0): below the margin, or deeper than the robot already is. Braking
from ω covers ω²/(2α), so the turn that way is bounded by

    |ω| ≤ √(2αθ),

never below ``turn_speed_floor`` (a robot with someone at its margin can
still turn, slowly), and free where the whole sweep is clear. Turning away
from a person is not limited. The bounds hold at the knots within the
yaw's stopping time, each no tighter than braking from the measured ω at
0.8 α allows (they stay feasible, with room: ν_0 is pinned to the
measured velocity).
Translation is the DT-CBF's and the guard's.
"""

import math

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.robots.planar_base import NumBaseVelocities

# Sampled angles of each direction's braking sweep.
SWEEP_SAMPLES = 48
# A measured turn faster than its bound is held no tighter than braking at
# this share of the yaw deceleration limit allows.
BRAKING_SHARE = 0.8


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
) -> tuple[int, np.ndarray, np.ndarray] | None:
    """The yaw rate's bounds (module doc): (the ν index of the yaw rate,
    lower and upper bounds for knots 1 … K), or None where nothing binds
    (nobody tracked, or every sweep is clear). ``people`` (P, 2): the
    tracked people's measured positions."""
    people = np.asarray(people, dtype=float).reshape(-1, 2)
    people = people[np.all(np.isfinite(people), axis=1)]
    q0 = np.asarray(q0, dtype=float)
    if people.size == 0 or not np.all(np.isfinite(q0)):
        return None
    # Nobody within the robot's reach (its farthest body's, turning about the
    # base's centre) plus their margin: no turn can reach them.
    ends = robot.CalcKinematics(q0[None]).capsule_points[0, :, :, :2]
    reach = np.max(
        np.linalg.norm(ends - q0[None, None, :2], axis=2).max(axis=1)
        + robot.capsule_radii
    )
    if (
        np.min(np.linalg.norm(people - q0[:2], axis=1))
        > reach + human_radius + human_margin
    ):
        return None
    w = NumBaseVelocities(robot) - 1
    top = min(-robot.nu_lower[w], robot.nu_upper[w])
    alpha = min(-robot.nudot_lower[w], robot.nudot_upper[w])
    angles = np.linspace(0.0, top * top / (2.0 * alpha), SWEEP_SAMPLES + 1)
    turns = np.concatenate([angles, -angles[1:]])
    qs = np.repeat(q0[None], turns.size, axis=0)
    qs[:, 2] += turns
    ends = robot.CalcKinematics(qs).capsule_points[..., :2]  # (T, C, 2, 2)
    d, _, _ = point_segment_distance_2d(
        ends[:, None, :, 0], ends[:, None, :, 1], people[None, :, None, :]
    )  # (T, P, C)
    offset = robot.capsule_radii + human_radius + human_margin
    h = np.min(d - offset, axis=(1, 2))  # (T,)
    threshold = min(h[0], 0.0) - 1e-9
    bounds = []
    for sweep in (h[: angles.size], np.concatenate([h[:1], h[angles.size :]])):
        bad = np.nonzero(sweep < threshold)[0]
        theta = angles[bad[0] - 1] if bad.size else np.inf
        bounds.append(max(float(floor), math.sqrt(2.0 * alpha * theta)))
    upper, lower = bounds
    if upper >= top and lower >= top:
        return None
    # The knots within the yaw's stopping time from its top rate.
    steps = min(int(horizon), math.ceil(top / alpha / time_step - 1e-9))
    # Braking at BRAKING_SHARE of α: the bound then leaves the plan room
    # (at α itself it pins ν_k and u_k to a single point, a feasible set
    # without interior that PIQP declared infeasible).
    braking = BRAKING_SHARE * alpha * time_step * np.arange(1, steps + 1)
    omega0 = float(nu0[w]) if np.isfinite(nu0[w]) else 0.0
    up = np.minimum(np.maximum(upper, omega0 - braking), top)
    down = np.minimum(np.maximum(lower, -omega0 - braking), top)
    return w, -down, up
