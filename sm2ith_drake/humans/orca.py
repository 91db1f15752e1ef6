"""ORCA (van den Berg, Guy, Lin, Manocha 2011) exactly as the RVO2 library
builds it, in numpy: the ORCA half-planes of one agent and its new velocity.

Public functions:

- :func:`orca_half_planes` — RVO2's ``orcaLines_`` (static obstacles first,
  then agents, each group sorted by distance as RVO2's neighbour queries do):
  lines (point, unit direction); allowed velocities lie to the *left* of the
  direction, i.e. n·v ≥ n·point with n the left normal
  (:func:`half_plane_normal_form`).
- :func:`orca_velocity` — the new velocity: RVO2's ``linearProgram2`` on the
  speed disc, and ``linearProgram3`` (minimum penetration, obstacle lines
  kept hard) when the lines are infeasible.

Obstacles are polygons given by their vertices in counter-clockwise order, or
line segments (two vertices), as RVO2's ``addObstacle`` takes them. What is
not reproduced: RVO2's kd-tree splits obstacle edges that cross another
edge's supporting line; scenes whose obstacle edges do not cross other edges'
lines (walls, boxes apart from each other) are unaffected.
"""

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.humans.kernels import agent_lines

RVO_EPSILON = 1e-5


def _Det(a, b):
    return float(a[0] * b[1] - a[1] * b[0])


def _Normalize(v):
    return v / np.linalg.norm(v)


class _ObstacleVertex:
    __slots__ = ("point", "next", "prev", "unit_dir", "is_convex")


def _MakeObstacles(obstacles):
    """RVO2's obstacle vertex rings (addObstacle)."""
    vertices = []
    for poly in obstacles:
        pts = [np.asarray(p, dtype=float) for p in np.asarray(poly, dtype=float)]
        if len(pts) < 2:
            raise ValueError("an obstacle needs at least two vertices")
        ring = []
        for p in pts:
            v = _ObstacleVertex()
            v.point = p
            ring.append(v)
        n = len(ring)
        for i, v in enumerate(ring):
            v.next = ring[(i + 1) % n]
            v.prev = ring[(i - 1) % n]
            v.unit_dir = _Normalize(v.next.point - v.point)
            if n == 2:
                v.is_convex = True
            else:
                a, b, c = v.prev.point, v.point, v.next.point
                v.is_convex = _Det(a - c, b - a) >= 0.0  # leftOf(prev, this, next)
        vertices += ring
    return vertices


def _LeftLeg(rel, dist_sq, radius):
    """Direction of the left tangent from the agent to a disc of ``radius``
    at relative position ``rel`` (RVO2's left leg)."""
    leg = np.sqrt(dist_sq - radius * radius)
    return (
        np.array([rel[0] * leg - rel[1] * radius, rel[0] * radius + rel[1] * leg])
        / dist_sq
    )


def _RightLeg(rel, dist_sq, radius):
    """Direction of the right tangent (RVO2's right leg)."""
    leg = np.sqrt(dist_sq - radius * radius)
    return (
        np.array([rel[0] * leg + rel[1] * radius, -rel[0] * radius + rel[1] * leg])
        / dist_sq
    )


def _ObstacleLines(position, velocity, radius, vertices, tau_obs, range_sq):
    """RVO2's obstacle ORCA lines (Agent::computeNewVelocity, first part)."""
    lines = []
    neighbors = []
    for v1 in vertices:
        v2 = v1.next
        # Only edges the agent is to the right of (outside), within range.
        # RVO2's leftOf(p1, p2, agent) = det(p1 − agent, p2 − p1).
        if _Det(v1.point - position, v2.point - v1.point) >= 0.0:
            continue
        dist_sq = float(point_segment_distance_2d(v1.point, v2.point, position)[0] ** 2)
        if dist_sq < range_sq:
            neighbors.append((dist_sq, v1))
    neighbors.sort(key=lambda x: x[0])
    inv_tau = 1.0 / tau_obs
    radius_sq = radius * radius
    for _, obstacle1 in neighbors:
        obstacle2 = obstacle1.next
        rel1 = obstacle1.point - position
        rel2 = obstacle2.point - position
        covered = False
        for point, direction in lines:
            if (
                _Det(inv_tau * rel1 - point, direction) - inv_tau * radius
                >= -RVO_EPSILON
                and _Det(inv_tau * rel2 - point, direction) - inv_tau * radius
                >= -RVO_EPSILON
            ):
                covered = True
                break
        if covered:
            continue
        dist_sq1 = float(rel1 @ rel1)
        dist_sq2 = float(rel2 @ rel2)
        obstacle_vector = obstacle2.point - obstacle1.point
        s = float(-rel1 @ obstacle_vector) / float(obstacle_vector @ obstacle_vector)
        diff = -rel1 - s * obstacle_vector
        dist_sq_line = float(diff @ diff)
        if s < 0.0 and dist_sq1 <= radius_sq:
            if obstacle1.is_convex:
                lines.append((np.zeros(2), _Normalize(np.array([-rel1[1], rel1[0]]))))
            continue
        if s > 1.0 and dist_sq2 <= radius_sq:
            if obstacle2.is_convex and _Det(rel2, obstacle2.unit_dir) >= 0.0:
                lines.append((np.zeros(2), _Normalize(np.array([-rel2[1], rel2[0]]))))
            continue
        if 0.0 <= s < 1.0 and dist_sq_line <= radius_sq:
            lines.append((np.zeros(2), -obstacle1.unit_dir))
            continue
        # No collision: the legs.
        if s < 0.0 and dist_sq_line <= radius_sq:
            if not obstacle1.is_convex:
                continue
            obstacle2 = obstacle1
            left_leg = _LeftLeg(rel1, dist_sq1, radius)
            right_leg = _RightLeg(rel1, dist_sq1, radius)
        elif s > 1.0 and dist_sq_line <= radius_sq:
            if not obstacle2.is_convex:
                continue
            obstacle1 = obstacle2
            left_leg = _LeftLeg(rel2, dist_sq2, radius)
            right_leg = _RightLeg(rel2, dist_sq2, radius)
        else:
            left_leg = (
                _LeftLeg(rel1, dist_sq1, radius)
                if obstacle1.is_convex
                else -obstacle1.unit_dir
            )
            right_leg = (
                _RightLeg(rel2, dist_sq2, radius)
                if obstacle2.is_convex
                else obstacle1.unit_dir
            )
        left_neighbor = obstacle1.prev
        left_foreign = right_foreign = False
        if obstacle1.is_convex and _Det(left_leg, -left_neighbor.unit_dir) >= 0.0:
            left_leg = -left_neighbor.unit_dir
            left_foreign = True
        if obstacle2.is_convex and _Det(right_leg, obstacle2.unit_dir) <= 0.0:
            right_leg = obstacle2.unit_dir
            right_foreign = True
        left_cutoff = inv_tau * (obstacle1.point - position)
        right_cutoff = inv_tau * (obstacle2.point - position)
        cutoff_vec = right_cutoff - left_cutoff
        same = obstacle1 is obstacle2
        t = (
            0.5
            if same
            else float((velocity - left_cutoff) @ cutoff_vec)
            / float(cutoff_vec @ cutoff_vec)
        )
        t_left = float((velocity - left_cutoff) @ left_leg)
        t_right = float((velocity - right_cutoff) @ right_leg)
        if (t < 0.0 and t_left < 0.0) or (same and t_left < 0.0 and t_right < 0.0):
            unit_w = _Normalize(velocity - left_cutoff)
            lines.append(
                (
                    left_cutoff + radius * inv_tau * unit_w,
                    np.array([unit_w[1], -unit_w[0]]),
                )
            )
            continue
        if t > 1.0 and t_right < 0.0:
            unit_w = _Normalize(velocity - right_cutoff)
            lines.append(
                (
                    right_cutoff + radius * inv_tau * unit_w,
                    np.array([unit_w[1], -unit_w[0]]),
                )
            )
            continue
        inf = np.inf
        d_cut = (
            inf
            if (t < 0.0 or t > 1.0 or same)
            else float(np.sum((velocity - (left_cutoff + t * cutoff_vec)) ** 2))
        )
        d_left = (
            inf
            if t_left < 0.0
            else float(np.sum((velocity - (left_cutoff + t_left * left_leg)) ** 2))
        )
        d_right = (
            inf
            if t_right < 0.0
            else float(np.sum((velocity - (right_cutoff + t_right * right_leg)) ** 2))
        )
        if d_cut <= d_left and d_cut <= d_right:
            direction = -obstacle1.unit_dir
            lines.append(
                (
                    left_cutoff
                    + radius * inv_tau * np.array([-direction[1], direction[0]]),
                    direction,
                )
            )
        elif d_left <= d_right:
            if left_foreign:
                continue
            direction = left_leg
            lines.append(
                (
                    left_cutoff
                    + radius * inv_tau * np.array([-direction[1], direction[0]]),
                    direction,
                )
            )
        else:
            if right_foreign:
                continue
            direction = -right_leg
            lines.append(
                (
                    right_cutoff
                    + radius * inv_tau * np.array([-direction[1], direction[0]]),
                    direction,
                )
            )
    return lines


def orca_agent_lines(rel_position, rel_velocity, combined_radius, *, tau, time_step):
    """ORCA's u and line direction for many agent pairs at once (RVO2's
    Agent::computeNewVelocity, agent part), vectorized.

    Args:
        rel_position: (..., 2) other agent's position minus this agent's.
        rel_velocity: (..., 2) this agent's velocity minus the other's.
        combined_radius: (...,) sum of the radii.

    Returns:
        u (..., 2), the smallest change of relative velocity to leave the
        velocity obstacle, and direction (..., 2) of the ORCA line. The line
        passes through v + share·u; allowed velocities lie to its left.
    """
    shape = np.broadcast_shapes(
        np.shape(rel_position),
        np.shape(rel_velocity),
        np.shape(combined_radius) + (2,),
    )
    # Contiguous, writeable copies of one shape (what the kernel takes).
    P, V, R = np.empty(shape), np.empty(shape), np.empty(shape[:-1])
    P[...], V[...], R[...] = rel_position, rel_velocity, combined_radius
    P, V, R = P.reshape(-1, 2), V.reshape(-1, 2), R.reshape(-1)
    u, direction = np.empty_like(P), np.empty_like(P)
    # Compiled: one pass over the pairs (humans/kernels.py).
    agent_lines(P, V, R, float(tau), float(time_step), u, direction)
    return u.reshape(shape), direction.reshape(shape)


def orca_half_planes(
    position,
    velocity,
    radius,
    other_positions,
    other_velocities,
    other_radii,
    *,
    tau=2.0,
    tau_obs=0.5,
    time_step,
    shares=None,
    obstacles=(),
    max_speed=None,
    neighbor_dist=np.inf,
):
    """The ORCA lines of one agent, as RVO2 builds them.

    Args:
        position, velocity, radius: the agent.
        other_positions, other_velocities, other_radii: the other agents
            (M, 2), (M, 2), (M,).
        tau, tau_obs: time horizons for agents (one, or one per other
            agent (M,)) and static obstacles (s).
        time_step: the simulation step (used when already colliding).
        shares: responsibility per other agent (default 0.5: reciprocal).
        obstacles: polygons (vertex lists, counter-clockwise) or segments.
        max_speed: with obstacles, RVO2 only considers obstacle edges within
            τ_obs·max_speed + radius (all of them if None).
        neighbor_dist: agents farther than this are ignored (RVO2's
            neighborDist).

    Returns:
        points (L, 2), directions (L, 2) and the number of obstacle lines
        (they come first).
    """
    position = np.asarray(position, dtype=float)
    velocity = np.asarray(velocity, dtype=float)
    other_positions = np.asarray(other_positions, dtype=float).reshape(-1, 2)
    other_velocities = np.asarray(other_velocities, dtype=float).reshape(-1, 2)
    other_radii = np.broadcast_to(
        np.asarray(other_radii, dtype=float), (len(other_positions),)
    )
    shares = (
        np.full(len(other_positions), 0.5)
        if shares is None
        else np.broadcast_to(np.asarray(shares, dtype=float), (len(other_positions),))
    )
    range_sq = np.inf if max_speed is None else (tau_obs * max_speed + radius) ** 2
    lines = _ObstacleLines(
        position, velocity, radius, _MakeObstacles(obstacles), tau_obs, range_sq
    )
    num_obstacle_lines = len(lines)
    dist_sq = np.sum((other_positions - position) ** 2, axis=1)
    order = np.argsort(dist_sq, kind="stable")
    order = order[dist_sq[order] < neighbor_dist**2]
    taus = np.broadcast_to(np.asarray(tau, dtype=float), (len(other_positions),))
    taus = taus[order]
    u, dirs = np.empty((len(order), 2)), np.empty((len(order), 2))
    for t in np.unique(taus):
        rows = taus == t
        u[rows], dirs[rows] = orca_agent_lines(
            other_positions[order[rows]] - position,
            velocity - other_velocities[order[rows]],
            radius + other_radii[order[rows]],
            tau=t,
            time_step=time_step,
        )
    lines += list(zip(velocity + shares[order, None] * u, dirs, strict=True))
    points = np.array([p for p, _ in lines]).reshape(-1, 2)
    directions = np.array([d for _, d in lines]).reshape(-1, 2)
    return points, directions, num_obstacle_lines


def half_plane_normal_form(points, directions):
    """Lines (point, direction) as half-planes n·v ≥ ρ (n the unit left
    normal of the direction)."""
    d = np.asarray(directions, dtype=float).reshape(-1, 2)
    n = np.column_stack([-d[:, 1], d[:, 0]])
    return n, np.sum(n * np.asarray(points, dtype=float).reshape(-1, 2), axis=1)
