"""Helbing's social force model (Helbing & Molnár 1995; Helbing, Farkas &
Vicsek 2000), for simulated people that do not follow ORCA.

Each person i accelerates toward its goal and is pushed away from others,
walls and the robot:

    dv_i/dt = (v0_i e_i − v_i)/τ_relax
              + Σ_j A exp((r_ij − d_ij)/B) n_ij          (people, robot)
              + Σ_w A_w exp((r_i − d_iw)/B_w) n_iw       (walls)

with d the centre distance, r the sum of radii and n the unit vector away
from the other. The speed is clamped to 1.3 v0_i (Helbing's choice). When
bodies overlap, a contact force k (r − d) n is added as in the 2000 model.
"""

from dataclasses import dataclass

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d


@dataclass
class SocialForceParams:
    # Relaxation time toward the desired velocity (s) (Helbing 2000: 0.5).
    relaxation_time: float = 0.5
    # Person–person repulsion strength (m/s²) and range (m) (Helbing 2000:
    # A = 2000 N, B = 0.08 m for an 80 kg person → 25 m/s²; we use a softer,
    # longer-range variant common in crowd simulation).
    strength: float = 8.0
    range: float = 0.4
    # Wall repulsion.
    wall_strength: float = 10.0
    wall_range: float = 0.2
    # Body contact stiffness (1/s²) for overlaps.
    contact: float = 50.0
    # Speed cap as a multiple of the preferred speed.
    max_speed_factor: float = 1.3


def _PointSegment(p, a, b):
    """The closest point to p on the segment a–b."""
    _, s, _ = point_segment_distance_2d(a, b, p)
    return a + s[..., None] * (b - a)


def social_force_step(
    positions,
    velocities,
    goals,
    radii,
    *,
    dt,
    robot_position=None,
    robot_radius=0.0,
    robot_points=None,
    robot_point_radii=None,
    obstacles=(),
    max_speeds=None,
    params: SocialForceParams | None = None,
):
    """One explicit step of the social force model; returns the new
    positions and velocities (H, 2).

    The robot pushes each person like another person: from
    ``robot_position`` with ``robot_radius`` (its base disc), or, given
    ``robot_points`` (H, 2) and ``robot_point_radii`` (H,), from the point
    of the robot nearest to each person (so an arm sticking out pushes too,
    as a wall does from its closest point)."""
    params = params or SocialForceParams()
    p = np.asarray(positions, dtype=float).reshape(-1, 2)
    v = np.asarray(velocities, dtype=float).reshape(-1, 2)
    goals = np.asarray(goals, dtype=float).reshape(-1, 2)
    radii = np.asarray(radii, dtype=float).reshape(-1)
    H = len(p)
    v0 = np.ones(H) if max_speeds is None else np.asarray(max_speeds, dtype=float)
    to_goal = goals - p
    dist_goal = np.linalg.norm(to_goal, axis=1)
    e = to_goal / np.maximum(dist_goal, 1e-9)[:, None]
    # Slow down over the last metre so people stop at their goals.
    desired = e * (v0 * np.minimum(1.0, dist_goal))[:, None]
    force = (desired - v) / params.relaxation_time
    # Who pushes person i: every person, then (if any) the robot — its base
    # disc, or per person its nearest point. (H, H or H + 1).
    op, orad = np.broadcast_to(p[None], (H, H, 2)), np.broadcast_to(radii, (H, H))
    if robot_points is not None:
        rp = np.asarray(robot_points, dtype=float).reshape(H, 2)
        rr = np.asarray(robot_point_radii, dtype=float).reshape(H)
    elif robot_position is not None:
        rp = np.broadcast_to(np.asarray(robot_position, dtype=float)[:2], (H, 2))
        rr = np.full(H, float(robot_radius))
    else:
        rp = None
    if rp is not None:
        op = np.concatenate([op, rp[:, None]], axis=1)
        orad = np.concatenate([orad, rr[:, None]], axis=1)
    diff = p[:, None, :] - op
    d = np.linalg.norm(diff, axis=-1)
    n = diff / np.maximum(d, 1e-9)[..., None]
    r = radii[:, None] + orad
    mag = params.strength * np.exp((r - d) / params.range)
    mag += params.contact * np.maximum(r - d, 0.0)
    mag[np.arange(H), np.arange(H)] = 0.0  # nobody pushes themselves
    force += np.sum(mag[..., None] * n, axis=1)
    for segment in obstacles:
        a, b = np.asarray(segment, dtype=float)[0], np.asarray(segment, dtype=float)[1]
        c = _PointSegment(p, a, b)
        dw = p - c
        dist = np.linalg.norm(dw, axis=1)
        nw = dw / np.maximum(dist, 1e-9)[:, None]
        mag = params.wall_strength * np.exp((radii - dist) / params.wall_range)
        mag += params.contact * np.maximum(radii - dist, 0.0)
        force += mag[:, None] * nw
    new_v = v + dt * force
    speed = np.linalg.norm(new_v, axis=1)
    cap = params.max_speed_factor * v0
    new_v *= np.minimum(1.0, cap / np.maximum(speed, 1e-9))[:, None]
    return p + dt * new_v, new_v
