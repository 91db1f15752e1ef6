"""Optimal Reciprocal Collision Avoidance (ORCA) as the RVO2 library builds
it, and the relaxed-ORCA QP of the paper (Section IV.B).

Reference: J. van den Berg, S. J. Guy, M. Lin, D. Manocha, "Reciprocal
n-body collision avoidance", ISRR 2011, and its reference implementation
RVO2 (``Agent::computeNewVelocity``, v2.0.3). The code below follows RVO2
branch by branch, in double instead of single precision.

Half-planes
-----------
An ORCA line is a point on the line and a unit direction; the permissible
velocities lie to the LEFT of the direction (RVO2's convention: velocity z
violates the line when det(direction, point − z) > 0). In normal form
(:func:`half_plane_normal_form`) the line is n·z ≥ ρ with n the unit left
normal of the direction and ρ = n·point.

Agent lines (one per neighbour, in the order given): combined radius
R = r + r_j, relative position p = p_j − p, relative velocity v_rel =
v − v_j. Without collision (‖p‖ > R) the truncated velocity obstacle is the
cone of the legs cut off by the circle of radius R/τ centred at p/τ; u is
the smallest change of v_rel that leaves it (projection on the cutoff circle
or on the nearer leg). When colliding, the cutoff circle of the time step
(radius R/Δt at p/Δt) is used instead. The line passes through
v + share·u (RVO2: share = 0.5; here one share per neighbour, e.g. a human
takes a larger share of the avoidance than 0.5 when the other agent is a
robot that does not react) with direction perpendicular to u.

Obstacle lines (static line segments, time horizon τ_obs): the subset of
RVO2's polygon-obstacle code that a two-vertex obstacle exercises, i.e.
what RVO2 does for ``addObstacle([a, b])``. RVO2 stores a segment as two
directed edges a→b and b→a, both convex vertices, and an agent only sees
the edge it is on the right of. For every segment, nearest first (RVO2
sorts obstacle neighbours by distance):

1. skip it if its velocity obstacle is already covered by the obstacle
   lines built so far (both endpoints, scaled by 1/τ_obs, lie on the
   forbidden side of one earlier line by at least the scaled radius);
2. collision with an endpoint or with the segment: a line through the
   origin (move away);
3. otherwise the legs from the endpoints (or both legs from one endpoint
   when the segment is seen obliquely), with RVO2's "foreign leg" rule for
   legs pointing into the segment, and the current velocity projected on
   the left/right cutoff circle, the cutoff line or a leg, whichever is
   nearest (a projection on a foreign leg adds no line).

Not implemented (documented deviations from RVO2):

- Polygons with more than two vertices (non-convex vertices, one-sided
  edges). Give walls as segments.
- RVO2's obstacle k-d tree splits an edge at the supporting line of another
  edge that crosses it (this changes the vertex structure). Segments here
  are never split; the result equals RVO2's when no segment's supporting
  line cuts another segment.
- RVO2 ignores a segment whose supporting line passes exactly through the
  agent (its tree query needs the agent strictly on an edge's right); here
  such a segment is kept, oriented a→b.
- Neighbour search: every given agent is a neighbour (RVO2 with an
  unbounded ``neighborDist`` and ``maxNeighbors``). Obstacle segments
  farther than τ_obs·max_speed + r are ignored when ``max_speed`` is given,
  as in RVO2.

Obstacle lines come first and agent lines after, as in RVO2.

New velocity
------------
:func:`orca_velocity` is RVO2's ``linearProgram2`` (the velocity closest to
the preferred one inside the speed circle and all lines) with its
``linearProgram3`` fallback when the lines are infeasible (minimize the
largest violation of the agent lines, obstacle lines kept hard). The lines
are taken in RVO2's order: obstacles by distance, then agents by distance.

Relaxed ORCA QP
---------------
:func:`relaxed_orca_action` solves eq. (relaxed_orca_acc_argmin) of the
paper with a primal-dual interior-point method; see its docstring.
"""

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

# RVO2's tolerance (Vector2.cc) for parallel lines and covered obstacles.
_RVO_EPSILON = 1e-5


def _Det(a, b):
    """The 2D cross product a × b, vectorized over leading axes."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _Normalize(v):
    return v / np.linalg.norm(v)


class OrcaLines(NamedTuple):
    """ORCA half-planes in RVO2's line form (obstacle lines first)."""

    points: np.ndarray  # (H, 2), a point on each line
    directions: np.ndarray  # (H, 2), unit; the permissible side is the left
    num_obstacle_lines: int  # rows [0, num_obstacle_lines) are obstacle lines


def half_plane_normal_form(
    points: np.ndarray, directions: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Converts lines (point, unit direction, permissible side on the left)
    to the normal form n·z ≥ ρ.

    Returns:
        normals (H, 2), the unit left normals (−d_y, d_x), and offsets ρ (H,),
        ρ = n·point.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    directions = np.asarray(directions, dtype=float).reshape(-1, 2)
    normals = np.stack([-directions[:, 1], directions[:, 0]], axis=-1)
    return normals, np.sum(normals * points, axis=-1)


def orca_agent_lines(
    position,
    velocity,
    radius: float,
    other_positions,
    other_velocities,
    other_radii,
    *,
    tau: float,
    time_step: float,
    shares=None,
) -> tuple[np.ndarray, np.ndarray]:
    """ORCA lines induced by other agents (RVO2's agent part), vectorized.

    Args:
        position, velocity: this agent's (2,).
        radius: this agent's radius.
        other_positions, other_velocities: (K, 2).
        other_radii: (K,) or a scalar.
        tau: time horizon τ (s).
        time_step: Δt (s), used when two agents already overlap.
        shares: (K,) or scalar responsibility for each pair; None means 0.5
            (RVO2's reciprocal split).

    Returns:
        points (K, 2), directions (K, 2), one line per other agent, in the
        order given.
    """
    p = np.asarray(position, dtype=float).reshape(2)
    v = np.asarray(velocity, dtype=float).reshape(2)
    P = np.asarray(other_positions, dtype=float).reshape(-1, 2) - p
    V = v - np.asarray(other_velocities, dtype=float).reshape(-1, 2)
    K = len(P)
    R = radius + np.broadcast_to(np.asarray(other_radii, dtype=float), (K,))
    share = np.broadcast_to(
        np.asarray(0.5 if shares is None else shares, dtype=float), (K,)
    )
    dist_sq = np.sum(P * P, axis=-1)
    R_sq = R * R
    colliding = dist_sq <= R_sq

    with np.errstate(divide="ignore", invalid="ignore"):
        # No collision: w is the relative velocity seen from the cutoff centre.
        w = V - P / tau
        w_len_sq = np.sum(w * w, axis=-1)
        dot = np.sum(w * P, axis=-1)
        on_cutoff = (dot < 0.0) & (dot * dot > R_sq * w_len_sq)
        w_len = np.sqrt(w_len_sq)
        unit_w = w / w_len[:, None]
        dir_cutoff = np.stack([unit_w[:, 1], -unit_w[:, 0]], axis=-1)
        u_cutoff = (R / tau - w_len)[:, None] * unit_w

        leg = np.sqrt(np.maximum(dist_sq - R_sq, 0.0))
        px, py = P[:, 0], P[:, 1]
        dir_left = np.stack([px * leg - py * R, px * R + py * leg], -1)
        dir_right = -np.stack([px * leg + py * R, -px * R + py * leg], -1)
        on_left_leg = _Det(P, w) > 0.0
        dir_leg = np.where(on_left_leg[:, None], dir_left, dir_right)
        dir_leg = dir_leg / dist_sq[:, None]
        u_leg = np.sum(V * dir_leg, axis=-1)[:, None] * dir_leg - V

        # Collision: the cutoff circle of the time step.
        w_col = V - P / time_step
        w_col_len = np.linalg.norm(w_col, axis=-1)
        unit_col = w_col / w_col_len[:, None]
    # RVO2 divides by zero when the relative velocity sits exactly at the
    # centre of the collision circle; any direction is then a smallest
    # escape: take the one away from the other agent.
    degenerate = w_col_len == 0.0
    if np.any(degenerate):
        dist = np.sqrt(dist_sq[degenerate])
        away = np.where(
            dist[:, None] > 0.0,
            -P[degenerate] / np.where(dist > 0.0, dist, 1.0)[:, None],
            np.array([-1.0, 0.0]),
        )
        unit_col[degenerate] = away
    dir_col = np.stack([unit_col[:, 1], -unit_col[:, 0]], axis=-1)
    u_col = (R / time_step - w_col_len)[:, None] * unit_col

    direction = np.where(on_cutoff[:, None], dir_cutoff, dir_leg)
    u = np.where(on_cutoff[:, None], u_cutoff, u_leg)
    direction = np.where(colliding[:, None], dir_col, direction)
    u = np.where(colliding[:, None], u_col, u)
    return v + share[:, None] * u, direction


def _SegmentDistanceSq(a, b, c) -> float:
    """Squared distance from point c to segment a–b (RVO2's
    ``distSqPointLineSegment``)."""
    ab = b - a
    r = (c - a) @ ab / (ab @ ab)
    if r < 0.0:
        return float((c - a) @ (c - a))
    if r > 1.0:
        return float((c - b) @ (c - b))
    d = c - (a + r * ab)
    return float(d @ d)


def _Segments(obstacles) -> np.ndarray:
    segments = np.asarray(
        [np.asarray(s, dtype=float).reshape(2, 2) for s in obstacles], dtype=float
    ).reshape(-1, 2, 2)
    if np.any(np.all(segments[:, 0] == segments[:, 1], axis=-1)):
        raise ValueError("orca: an obstacle segment has coincident endpoints")
    return segments


def orca_obstacle_lines(
    position,
    velocity,
    radius: float,
    obstacles,
    *,
    tau_obs: float,
    max_speed: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """ORCA lines of static line segments, as RVO2 builds them for two-vertex
    obstacles (see the module doc for the exact subset).

    Args:
        position, velocity: this agent's (2,).
        radius: this agent's radius.
        obstacles: segments, each two endpoints ((x0, y0), (x1, y1)).
        tau_obs: time horizon for obstacles τ_obs (s).
        max_speed: if given, segments at distance ≥ τ_obs·max_speed + radius
            are ignored (RVO2's obstacle neighbour range).

    Returns:
        points (L, 2), directions (L, 2), L ≤ number of segments, nearest
        segment first.
    """
    p = np.asarray(position, dtype=float).reshape(2)
    v = np.asarray(velocity, dtype=float).reshape(2)
    segments = _Segments(obstacles)
    range_sq = np.inf if max_speed is None else (tau_obs * max_speed + radius) ** 2

    # Orient each segment so that the agent is on the right of edge a→b,
    # the one edge of the pair RVO2's obstacle tree reports, and sort by
    # distance (stable, like RVO2's insertion sort).
    neighbours = []
    for a, b in segments:
        if _Det(a - p, b - a) > 0.0:  # RVO2's leftOf(a, b, p) > 0
            a, b = b, a
        dist_sq = _SegmentDistanceSq(a, b, p)
        if dist_sq < range_sq:
            neighbours.append((dist_sq, a, b))
    neighbours.sort(key=lambda item: item[0])

    inv_tau = 1.0 / tau_obs
    radius_sq = radius * radius
    points, directions = [], []

    def _Push(point, direction):
        points.append(np.asarray(point, dtype=float))
        directions.append(np.asarray(direction, dtype=float))

    for _, a, b in neighbours:
        # RVO2's vertex structure of a two-vertex obstacle: vertex 1 = a with
        # direction d (towards b), vertex 2 = b with direction −d; each is
        # the other's previous and next vertex, and both are convex.
        d = _Normalize(b - a)
        rel1 = a - p
        rel2 = b - p

        # 1. Already covered by a previous obstacle line?
        covered = False
        for q, e in zip(points, directions, strict=True):
            if (
                _Det(inv_tau * rel1 - q, e) - inv_tau * radius >= -_RVO_EPSILON
                and _Det(inv_tau * rel2 - q, e) - inv_tau * radius >= -_RVO_EPSILON
            ):
                covered = True
                break
        if covered:
            continue

        # 2. Collision.
        dist_sq1 = rel1 @ rel1
        dist_sq2 = rel2 @ rel2
        ab = b - a
        s = (-rel1 @ ab) / (ab @ ab)
        dist_sq_line = np.sum((-rel1 - s * ab) ** 2)
        if s < 0.0 and dist_sq1 <= radius_sq:  # with the left vertex
            _Push([0.0, 0.0], _Normalize(np.array([-rel1[1], rel1[0]])))
            continue
        if s > 1.0 and dist_sq2 <= radius_sq:  # with the right vertex
            # RVO2 leaves it to the neighbouring edge unless that edge points
            # away; for a segment the neighbouring edge is b→a (direction −d).
            if _Det(rel2, -d) >= 0.0:
                _Push([0.0, 0.0], _Normalize(np.array([-rel2[1], rel2[0]])))
            continue
        if 0.0 <= s <= 1.0 and dist_sq_line <= radius_sq:  # with the segment
            _Push([0.0, 0.0], -d)
            continue

        # 3. No collision: legs. vertex1/vertex2 are (point, direction,
        # direction of the previous vertex) in RVO2's pointer structure.
        vertex1 = (a, d, -d)
        vertex2 = (b, -d, d)
        if s < 0.0 and dist_sq_line <= radius_sq:
            # Seen obliquely: the left vertex defines both legs.
            vertex2 = vertex1
            leg = np.sqrt(dist_sq1 - radius_sq)
            x, y = rel1
            left_leg = np.array([x * leg - y * radius, x * radius + y * leg]) / dist_sq1
            right_leg = (
                np.array([x * leg + y * radius, -x * radius + y * leg]) / dist_sq1
            )
        elif s > 1.0 and dist_sq_line <= radius_sq:
            # Seen obliquely: the right vertex defines both legs.
            vertex1 = vertex2
            leg = np.sqrt(dist_sq2 - radius_sq)
            x, y = rel2
            left_leg = np.array([x * leg - y * radius, x * radius + y * leg]) / dist_sq2
            right_leg = (
                np.array([x * leg + y * radius, -x * radius + y * leg]) / dist_sq2
            )
        else:
            leg1 = np.sqrt(dist_sq1 - radius_sq)
            x, y = rel1
            left_leg = (
                np.array([x * leg1 - y * radius, x * radius + y * leg1]) / dist_sq1
            )
            leg2 = np.sqrt(dist_sq2 - radius_sq)
            x, y = rel2
            right_leg = (
                np.array([x * leg2 + y * radius, -x * radius + y * leg2]) / dist_sq2
            )

        # A leg that points into the neighbouring edge is replaced by that
        # edge ("foreign" leg); a projection on it adds no line.
        left_foreign = right_foreign = False
        if _Det(left_leg, -vertex1[2]) >= 0.0:
            left_leg = -vertex1[2]
            left_foreign = True
        if _Det(right_leg, vertex2[1]) <= 0.0:
            right_leg = vertex2[1].copy()
            right_foreign = True

        left_cutoff = inv_tau * (vertex1[0] - p)
        right_cutoff = inv_tau * (vertex2[0] - p)
        cutoff_vec = right_cutoff - left_cutoff
        same_vertex = vertex1 is vertex2

        t = (
            0.5
            if same_vertex
            else (v - left_cutoff) @ cutoff_vec / (cutoff_vec @ cutoff_vec)
        )
        t_left = (v - left_cutoff) @ left_leg
        t_right = (v - right_cutoff) @ right_leg

        if (t < 0.0 and t_left < 0.0) or (
            same_vertex and t_left < 0.0 and t_right < 0.0
        ):
            unit_w = _Normalize(v - left_cutoff)  # left cutoff circle
            _Push(left_cutoff + radius * inv_tau * unit_w, [unit_w[1], -unit_w[0]])
            continue
        if t > 1.0 and t_right < 0.0:
            unit_w = _Normalize(v - right_cutoff)  # right cutoff circle
            _Push(right_cutoff + radius * inv_tau * unit_w, [unit_w[1], -unit_w[0]])
            continue

        # Nearest of the cutoff line and the two legs.
        dist_sq_cutoff = (
            np.inf
            if (t < 0.0 or t > 1.0 or same_vertex)
            else np.sum((v - (left_cutoff + t * cutoff_vec)) ** 2)
        )
        dist_sq_left = (
            np.inf
            if t_left < 0.0
            else np.sum((v - (left_cutoff + t_left * left_leg)) ** 2)
        )
        dist_sq_right = (
            np.inf
            if t_right < 0.0
            else np.sum((v - (right_cutoff + t_right * right_leg)) ** 2)
        )
        if dist_sq_cutoff <= dist_sq_left and dist_sq_cutoff <= dist_sq_right:
            direction = -vertex1[1]
            _Push(
                left_cutoff
                + radius * inv_tau * np.array([-direction[1], direction[0]]),
                direction,
            )
            continue
        if dist_sq_left <= dist_sq_right:
            if not left_foreign:
                direction = left_leg
                _Push(
                    left_cutoff
                    + radius * inv_tau * np.array([-direction[1], direction[0]]),
                    direction,
                )
            continue
        if not right_foreign:
            direction = -right_leg
            _Push(
                right_cutoff
                + radius * inv_tau * np.array([-direction[1], direction[0]]),
                direction,
            )

    return (
        np.asarray(points, dtype=float).reshape(-1, 2),
        np.asarray(directions, dtype=float).reshape(-1, 2),
    )


def orca_half_planes(
    position,
    velocity,
    radius: float,
    other_positions,
    other_velocities,
    other_radii,
    *,
    tau: float = 2.0,
    tau_obs: float = 0.5,
    time_step: float,
    shares=None,
    obstacles=(),
    max_speed: float | None = None,
) -> OrcaLines:
    """All ORCA half-planes of one agent, as RVO2's ``computeNewVelocity``
    builds them: obstacle lines first (nearest segment first), then one line
    per other agent in the order given.

    Args:
        position, velocity: this agent's position and current velocity (2,).
        radius: this agent's radius (m).
        other_positions, other_velocities: (K, 2); other_radii (K,) or scalar.
        tau: time horizon τ for agents (s).
        tau_obs: time horizon τ_obs for static obstacles (s).
        time_step: Δt (s); used for pairs that already overlap.
        shares: per-neighbour share of the avoidance (K,) or scalar; None is
            RVO2's 0.5.
        obstacles: static line segments, each ((x0, y0), (x1, y1)).
        max_speed: if given, ignore segments beyond RVO2's obstacle range
            τ_obs·max_speed + radius.

    Returns:
        OrcaLines(points, directions, num_obstacle_lines).
    """
    obs_points, obs_dirs = orca_obstacle_lines(
        position, velocity, radius, obstacles, tau_obs=tau_obs, max_speed=max_speed
    )
    agent_points, agent_dirs = orca_agent_lines(
        position,
        velocity,
        radius,
        other_positions,
        other_velocities,
        other_radii,
        tau=tau,
        time_step=time_step,
        shares=shares,
    )
    return OrcaLines(
        np.vstack([obs_points, agent_points]),
        np.vstack([obs_dirs, agent_dirs]),
        len(obs_points),
    )


# RVO2's incremental linear programs (Agent.cc), on lists of Python floats.


def _LinearProgram1(lines, line_no, radius, opt, direction_opt):
    """Optimizes on line ``line_no`` subject to lines [0, line_no) and the
    circle; returns the result or None if infeasible."""
    (px, py), (dx, dy) = lines[line_no]
    dot = px * dx + py * dy
    discriminant = dot * dot + radius * radius - (px * px + py * py)
    if discriminant < 0.0:
        return None  # the speed circle fully invalidates this line
    sqrt_disc = np.sqrt(discriminant)
    t_left = -dot - sqrt_disc
    t_right = -dot + sqrt_disc
    for i in range(line_no):
        (qx, qy), (ex, ey) = lines[i]
        denominator = dx * ey - dy * ex
        numerator = ex * (py - qy) - ey * (px - qx)
        if abs(denominator) <= _RVO_EPSILON:
            if numerator < 0.0:  # (almost) parallel and infeasible
                return None
            continue
        t = numerator / denominator
        if denominator >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        t = t_right if opt[0] * dx + opt[1] * dy > 0.0 else t_left
    else:
        t = dx * (opt[0] - px) + dy * (opt[1] - py)
        t = min(max(t, t_left), t_right)
    return (px + t * dx, py + t * dy)


def _LinearProgram2(lines, radius, opt, direction_opt):
    """Returns (result, index of the first infeasible line or len(lines))."""
    if direction_opt:
        result = (opt[0] * radius, opt[1] * radius)
    elif opt[0] ** 2 + opt[1] ** 2 > radius * radius:
        norm = np.hypot(opt[0], opt[1])
        result = (opt[0] / norm * radius, opt[1] / norm * radius)
    else:
        result = (opt[0], opt[1])
    for i, ((px, py), (dx, dy)) in enumerate(lines):
        if dx * (py - result[1]) - dy * (px - result[0]) > 0.0:
            new_result = _LinearProgram1(lines, i, radius, opt, direction_opt)
            if new_result is None:
                return result, i
            result = new_result
    return result, len(lines)


def _LinearProgram3(lines, num_obstacle_lines, begin_line, radius, result):
    """Minimizes the largest violation of the agent lines (from
    ``begin_line``), keeping the obstacle lines hard."""
    distance = 0.0
    for i in range(begin_line, len(lines)):
        (px, py), (dx, dy) = lines[i]
        if dx * (py - result[1]) - dy * (px - result[0]) <= distance:
            continue
        proj_lines = list(lines[:num_obstacle_lines])
        for j in range(num_obstacle_lines, i):
            (qx, qy), (ex, ey) = lines[j]
            determinant = dx * ey - dy * ex
            if abs(determinant) <= _RVO_EPSILON:
                if dx * ex + dy * ey > 0.0:
                    continue  # parallel, same direction
                point = (0.5 * (px + qx), 0.5 * (py + qy))  # opposite
            else:
                s = (ex * (py - qy) - ey * (px - qx)) / determinant
                point = (px + s * dx, py + s * dy)
            fx, fy = ex - dx, ey - dy
            norm = np.hypot(fx, fy)
            proj_lines.append((point, (fx / norm, fy / norm)))
        new_result, fail = _LinearProgram2(proj_lines, radius, (-dy, dx), True)
        # A failure here is floating-point error; RVO2 keeps the result.
        if fail >= len(proj_lines):
            result = new_result
        distance = dx * (py - result[1]) - dy * (px - result[0])
    return result


def orca_velocity(
    position,
    velocity,
    radius: float,
    other_positions,
    other_velocities,
    other_radii,
    *,
    preferred_velocity,
    max_speed: float,
    tau: float = 2.0,
    tau_obs: float = 0.5,
    time_step: float,
    shares=None,
    obstacles=(),
) -> np.ndarray:
    """The new velocity RVO2 computes for one agent (see
    :func:`orca_half_planes` for the arguments): the velocity nearest to
    ``preferred_velocity`` within ``max_speed`` that satisfies every ORCA
    line, or, if none does, the one minimizing the largest agent-line
    violation while keeping the obstacle lines.

    Returns:
        The new velocity (2,).
    """
    lines = orca_half_planes(
        position,
        velocity,
        radius,
        other_positions,
        other_velocities,
        other_radii,
        tau=tau,
        tau_obs=tau_obs,
        time_step=time_step,
        shares=shares,
        obstacles=obstacles,
        max_speed=max_speed,
    )
    n_obs = lines.num_obstacle_lines
    # RVO2 visits agent neighbours nearest first.
    dist_sq = np.sum(
        (np.asarray(other_positions, dtype=float).reshape(-1, 2) - position) ** 2,
        axis=-1,
    )
    order = np.concatenate(
        [np.arange(n_obs), n_obs + np.argsort(dist_sq, kind="stable")]
    ).astype(int)
    line_list = [(tuple(lines.points[k]), tuple(lines.directions[k])) for k in order]
    pref = tuple(np.asarray(preferred_velocity, dtype=float).reshape(2))
    result, fail = _LinearProgram2(line_list, max_speed, pref, False)
    if fail < len(line_list):
        result = _LinearProgram3(line_list, n_obs, fail, max_speed, result)
    return np.array(result, dtype=float)


@dataclass
class RelaxedOrcaSolution:
    """Solution and KKT multipliers of the relaxed-ORCA QP.

    With constraints written c ≤ 0 and multipliers λ ≥ 0 (μ ≥ 0 for ζ ≥ 0),
    stationarity reads

        2(z − v_des) + 2λ_s z + 2λ_a (z − v_t) − Σ_i λ_i n_i − Σ_o λ_o n_o = 0,
        2M_a ζ_a − λ_a − μ_a = 0,    2M_v,i ζ_v,i − λ_i − μ_i = 0.
    """

    velocity: np.ndarray  # z (2,)
    slack_acceleration: float  # ζ_a
    slack_velocity: np.ndarray  # ζ_v (A,), one per agent half-plane
    multiplier_speed: float  # λ_s of ‖z‖² − z_max² ≤ 0
    multiplier_acceleration: float  # λ_a of ‖z − v_t‖² − (Δt a_max)² − ζ_a ≤ 0
    multipliers_agents: np.ndarray  # λ_i of ρ_i − n_i·z − ζ_v,i ≤ 0 (A,)
    multipliers_static: np.ndarray  # λ_o of ρ_o − n_o·z ≤ 0 (S,)
    multiplier_slack_acceleration: float  # μ_a of −ζ_a ≤ 0
    multipliers_slack_velocity: np.ndarray  # μ_i of −ζ_v,i ≤ 0 (A,)
    cost: float  # ‖z − v_des‖² + M_a ζ_a² + Σ M_v,i ζ_v,i²
    kkt_residual: float  # max |stationarity|, violation, |complementarity|
    converged: bool
    iterations: int


def _PrimalDualInteriorPoint(
    x, Gradient, Constraints, *, tolerance, max_iterations, Stop=None
):
    """Primal-dual interior-point method for a small dense convex problem
    min f(x) s.t. c(x) < 0 from a strictly feasible x (Boyd & Vandenberghe,
    Convex Optimization, Algorithm 11.2, with its backtracking line search
    on the residual norm).

    Args:
        x: strictly feasible start (n,).
        Gradient(x, lam): (∇f (n,), ∇²f + Σ_j λ_j ∇²c_j (n, n)).
        Constraints(x): (c (m,), ∂c/∂x (m, n)).
        tolerance: on the dual residual (relative to the size of its terms);
            the surrogate duality gap −cᵀλ, which bounds f(x) − f*, is driven
            below 1e-3·tolerance, or below 10·tolerance if rounding stalls the
            iteration first.
        Stop(x): optional early exit (phase I).

    Returns:
        (x, λ, converged, iterations).
    """
    mu_factor = 10.0
    c, J = Constraints(x)
    m = len(c)
    lam = -1.0 / c
    converged = False
    iterations = 0

    def Residual(x, lam, t):
        c, J = Constraints(x)
        g, _ = Gradient(x, lam)
        return np.concatenate([g + J.T @ lam, -lam * c - 1.0 / t])

    for iterations in range(1, max_iterations + 1):  # noqa: B007
        if Stop is not None and Stop(x):
            converged = True
            break
        c, J = Constraints(x)
        g, H = Gradient(x, lam)
        r_dual = g + J.T @ lam
        gap = -c @ lam
        scale = 1.0 + np.max(np.abs(g) + np.abs(J.T) @ lam)
        dual_ok = np.max(np.abs(r_dual)) <= tolerance * scale
        if dual_ok and gap <= 1e-3 * tolerance:
            converged = True
            break
        t = mu_factor * m / gap
        r_cent = -lam * c - 1.0 / t
        # Eliminate dλ = (r_cent − λ∘(J dx))/c from the Newton system.
        K = H + J.T @ ((-lam / c)[:, None] * J)
        try:
            dx = np.linalg.solve(K, -r_dual - J.T @ (r_cent / c))
        except np.linalg.LinAlgError:
            # Only at the rounding floor: an active constraint's λ/|c| ~ 1e20.
            converged = dual_ok and gap <= 10.0 * tolerance
            break
        dlam = (r_cent - lam * (J @ dx)) / c
        negative = dlam < 0.0
        step = min(1.0, np.min(-lam[negative] / dlam[negative], initial=np.inf))
        step *= 0.99
        while np.any(Constraints(x + step * dx)[0] >= 0.0) and step > 1e-14:
            step *= 0.5
        norm = np.linalg.norm(np.concatenate([r_dual, r_cent]))
        while (
            np.linalg.norm(Residual(x + step * dx, lam + step * dlam, t))
            > (1.0 - 0.01 * step) * norm
            and step > 1e-14
        ):
            step *= 0.5
        if step <= 1e-14:
            # Stalled at the rounding floor.
            converged = dual_ok and gap <= 10.0 * tolerance
            break
        x = x + step * dx
        lam = lam + step * dlam
    return x, lam, converged, iterations


def _StrictlyFeasiblePoint(z, Hard, max_iterations):
    """A point strictly inside {z : h(z) < 0} (phase I: min σ s.t.
    h(z) ≤ σ), or None if the set has no interior."""
    h, _ = Hard(z)
    if np.max(h, initial=-1.0) < 0.0:
        return z
    z = np.zeros(2)
    h, _ = Hard(z)
    if np.max(h, initial=-1.0) < 0.0:
        return z
    margin = 1e-4

    def Constraints(y):
        h, G = Hard(y[:2])
        return h - y[2], np.hstack([G, -np.ones((len(h), 1))])

    def Gradient(y, lam):
        H = np.zeros((3, 3))
        H[0, 0] = H[1, 1] = 2.0 * lam[0]  # ‖z‖² − z_max² is row 0
        return np.array([0.0, 0.0, 1.0]), H

    y = np.array([0.0, 0.0, np.max(h) + 1.0])
    y, _, _, _ = _PrimalDualInteriorPoint(
        y,
        Gradient,
        Constraints,
        tolerance=1e-10,
        max_iterations=max_iterations,
        Stop=lambda y: y[2] < -margin,
    )
    h, _ = Hard(y[:2])
    return y[:2] if np.max(h) < 0.0 else None


def relaxed_orca_action(
    v_pref,
    v_current,
    normals,
    offsets,
    *,
    max_speed: float,
    max_accel: float,
    time_step: float,
    slack_weights,
    static_normals=None,
    static_offsets=None,
    tolerance: float = 1e-10,
    max_iterations: int = 100,
) -> RelaxedOrcaSolution:
    """Solves the relaxed-ORCA QP of one human (eq. relaxed_orca_acc_argmin):

        min_{z, ζ}  ‖z − v_des‖² + ζᵀMζ
        s.t.        ‖z‖² ≤ z_max²                                 (speed)
                    ‖z − v_t‖² ≤ (Δt·a_max)² + ζ_a                (acceleration)
                    n_iᵀz ≥ ρ_i − ζ_v,i   for each agent line i   (relaxed)
                    n_oᵀz ≥ ρ_o           for each static line o  (hard)
                    ζ = (ζ_a, ζ_v) ≥ 0,

    with M = diag(M_a, M_v,1, …, M_v,A) and one slack per agent line (as in
    SICNav, Samavi et al. 2024, Sec. III.B). The paper prints the
    acceleration constraint as ‖z − v_t‖² ≤ Δt·a_max − ζ_a; that is not
    dimensionally consistent (m²/s² against m/s) and a slack entering with
    a minus sign would tighten the constraint instead of keeping the QP
    feasible, as the paper says the slacks do. We square the bound and let
    the slack relax it.

    Because the slacks are penalized quadratically, ζ ≥ 0 never binds with
    a positive multiplier: at the optimum ζ_a = max(0, ‖z − v_t‖² −
    (Δt a_max)²), ζ_v,i = max(0, ρ_i − n_iᵀz), λ_a = 2M_aζ_a,
    λ_i = 2M_v,iζ_v,i and μ = 0. The solver therefore drops ζ ≥ 0 (the
    problem without it has the same solution and the same λ) and runs a
    primal-dual interior-point method (Boyd & Vandenberghe, Alg. 11.2) on
    the remaining convex QCQP in (z, ζ), started from a strictly feasible
    point (a phase I finds one inside the speed disc and the static
    half-planes when the preferred velocity is not). If those hard
    constraints have no interior (ORCA's static lines always admit z = 0,
    but may pin it there), the solver returns the phase-I point with
    ``converged=False``. Slacks and their multipliers are finally
    recomputed exactly from z by the formulas above.

    Args:
        v_pref: desired velocity v_des (2,).
        v_current: current velocity v_t (2,).
        normals, offsets: agent half-planes n_iᵀz ≥ ρ_i, (A, 2) and (A,)
            (e.g. from :func:`half_plane_normal_form`).
        max_speed: z_max (m/s).
        max_accel: a_max (m/s²); ``np.inf`` drops the acceleration
            constraint (then ζ_a = 0).
        time_step: Δt (s).
        slack_weights: (M_a, M_v), with M_v a scalar for every agent line, or
            the full diagonal (M_a, M_v,1, …, M_v,A); all > 0.
        static_normals, static_offsets: static half-planes (S, 2), (S,).
        tolerance: on the relative dual residual; the duality gap, which
            bounds the cost's suboptimality, is driven below 1e-3·tolerance
            (10·tolerance if rounding stalls the iteration first).
        max_iterations: interior-point iterations (per phase).

    Returns:
        RelaxedOrcaSolution.
    """
    v_des = np.asarray(v_pref, dtype=float).reshape(2)
    v_t = np.asarray(v_current, dtype=float).reshape(2)
    N = np.asarray(normals, dtype=float).reshape(-1, 2)
    rho = np.asarray(offsets, dtype=float).reshape(-1)
    Ns = np.zeros((0, 2)) if static_normals is None else static_normals
    Ns = np.asarray(Ns, dtype=float).reshape(-1, 2)
    rhos = np.zeros(0) if static_offsets is None else static_offsets
    rhos = np.asarray(rhos, dtype=float).reshape(-1)
    A, S = len(N), len(Ns)
    if len(rho) != A or len(rhos) != S:
        raise ValueError("relaxed_orca_action: normals and offsets differ in length")
    weights = np.atleast_1d(np.asarray(slack_weights, dtype=float))
    if weights.size == 2:
        M_a, M_v = weights[0], np.full(A, weights[1])
    elif weights.size == 1 + A:
        M_a, M_v = weights[0], weights[1:]
    else:
        raise ValueError(
            "relaxed_orca_action: slack_weights must be (M_a, M_v) "
            "or (M_a, M_v,1, …, M_v,A)"
        )
    if M_a <= 0 or np.any(M_v <= 0):
        raise ValueError("relaxed_orca_action: slack weights must be positive")
    if max_speed <= 0:
        raise ValueError("relaxed_orca_action: max_speed must be positive")
    has_acc = bool(np.isfinite(max_accel))
    r_acc_sq = (time_step * max_accel) ** 2 if has_acc else 0.0

    def Hard(z):
        """The hard constraints h(z) ≤ 0 (speed first) and their gradients."""
        h = np.concatenate([[z @ z - max_speed**2], rhos - Ns @ z])
        return h, np.vstack([2.0 * z, -Ns])

    # Variables x = (z, [ζ_a], ζ_v); constraints c(x) ≤ 0 in the order
    # speed, [acceleration], agents, static.
    ia = 2  # index of ζ_a (if has_acc)
    v0 = 2 + has_acc  # first ζ_v index
    n = v0 + A
    ra = 1 + has_acc  # first agent row
    rs = ra + A  # first static row
    m = rs + S
    weight_diag = np.concatenate([[1.0, 1.0], [M_a] * has_acc, M_v])
    J = np.zeros((m, n))
    J[ra:rs, :2] = -N
    J[ra:rs, v0:] = -np.eye(A)
    J[rs:, :2] = -Ns
    if has_acc:
        J[1, ia] = -1.0

    def Constraints(x):
        z = x[:2]
        c = np.empty(m)
        c[0] = z @ z - max_speed**2
        J[0, :2] = 2.0 * z
        if has_acc:
            e = z - v_t
            c[1] = e @ e - r_acc_sq - x[ia]
            J[1, :2] = 2.0 * e
        c[ra:rs] = rho - N @ z - x[v0:]
        c[rs:] = rhos - Ns @ z
        return c, J.copy()

    def Gradient(x, lam):
        g = 2.0 * weight_diag * x
        g[:2] -= 2.0 * v_des
        H = np.diag(2.0 * weight_diag)
        curvature = 2.0 * (lam[0] + (lam[1] if has_acc else 0.0))
        H[0, 0] += curvature
        H[1, 1] += curvature
        return g, H

    # Start: the desired velocity pulled inside the speed disc if that is
    # strictly feasible for the static lines, else a phase-I point; slacks
    # with a margin of 1.
    z0 = v_des * min(1.0, 0.99 * max_speed / max(np.linalg.norm(v_des), 1e-300))
    z0 = _StrictlyFeasiblePoint(z0, Hard, max_iterations)
    converged, iterations = False, 0
    if z0 is None:
        # No interior: report the most feasible point phase I can find.
        z = np.zeros(2)
        lam = np.zeros(m)
    else:
        x = np.zeros(n)
        x[:2] = z0
        if has_acc:
            x[ia] = max(0.0, (z0 - v_t) @ (z0 - v_t) - r_acc_sq) + 1.0
        x[v0:] = np.maximum(0.0, rho - N @ z0) + 1.0
        x, lam, converged, iterations = _PrimalDualInteriorPoint(
            x,
            Gradient,
            Constraints,
            tolerance=tolerance,
            max_iterations=max_iterations,
        )
        z = x[:2].copy()

    # The slacks and their multipliers follow exactly from z.
    zeta_a = max(0.0, (z - v_t) @ (z - v_t) - r_acc_sq) if has_acc else 0.0
    zeta_v = np.maximum(0.0, rho - N @ z)
    lam_s = float(lam[0])
    lam_a = 2.0 * M_a * zeta_a
    lam_v = 2.0 * M_v * zeta_v
    lam_o = lam[rs:].copy()
    stationarity = (
        2.0 * (z - v_des)
        + 2.0 * lam_s * z
        + 2.0 * lam_a * (z - v_t)
        - N.T @ lam_v
        - Ns.T @ lam_o
    )
    speed_c = z @ z - max_speed**2
    static_c = rhos - Ns @ z
    residual = max(
        np.max(np.abs(stationarity)),
        max(speed_c, 0.0),
        np.max(static_c, initial=0.0),
        abs(lam_s * speed_c),
        np.max(np.abs(lam_o * static_c), initial=0.0),
    )
    return RelaxedOrcaSolution(
        velocity=z,
        slack_acceleration=float(zeta_a),
        slack_velocity=zeta_v,
        multiplier_speed=lam_s,
        multiplier_acceleration=float(lam_a),
        multipliers_agents=lam_v,
        multipliers_static=lam_o,
        multiplier_slack_acceleration=0.0,
        multipliers_slack_velocity=np.zeros(A),
        cost=float((z - v_des) @ (z - v_des) + M_a * zeta_a**2 + M_v @ zeta_v**2),
        kkt_residual=float(residual),
        converged=converged,
        iterations=iterations,
    )
