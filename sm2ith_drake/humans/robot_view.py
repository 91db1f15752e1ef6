"""The robot as the people see it: its base, and its body nearest to each
person (the closest point on the nearest capsule's axis, moving with the
base), with the derivatives the KKT embedding needs.
"""

from dataclasses import dataclass

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d, segment_closest_points


@dataclass
class RobotView:
    """The robot at T steps as the people's ORCA sees it."""

    q: np.ndarray  # (T, n)
    nu: np.ndarray  # (T, m)
    p: np.ndarray  # (T, 2) base position
    v: np.ndarray  # (T, 2) base velocity in the world
    ends: np.ndarray  # (T, C, 2, 2) capsule axis end points on the floor
    ends_jacobian: np.ndarray  # (T, C, 2, 2, n) their Jacobians w.r.t. q
    radii: np.ndarray  # (C,)

    def Step(self, k: int) -> "RobotView":
        """The view of step k alone (T = 1)."""
        sl = slice(k, k + 1)
        return RobotView(
            self.q[sl],
            self.nu[sl],
            self.p[sl],
            self.v[sl],
            self.ends[sl],
            self.ends_jacobian[sl],
            self.radii,
        )


@dataclass
class NearestBody:
    """Per (step, person): the closest point on the axis of the robot capsule
    nearest to the person (surface distance), its radius, and the point's
    derivatives w.r.t. the configuration and the person's position."""

    point: np.ndarray  # (T, H, 2)
    radius: np.ndarray  # (T, H)
    d_dq: np.ndarray | None  # (T, H, 2, n)
    d_dp: np.ndarray | None  # (T, H, 2, 2)


def NearestBodies(robot: RobotView, positions, derivatives: bool = True) -> NearestBody:
    """The nearest robot body of every person (as
    NearestBodyOnFloor) with the derivatives of its closest point: for
    c = A + s(B − A), s = clip((P − A)·d / d·d) with d = B − A, the clipped
    ends move with A or B, and inside ∂s follows from the quotient rule.
    Without ``derivatives`` d_dq and d_dp are None (a forward simulation
    needs the points only)."""
    P = np.asarray(positions, dtype=float)  # (T, H, 2)
    A = robot.ends[:, None, :, 0]  # (T, 1, C, 2)
    B = robot.ends[:, None, :, 1]
    d = B - A
    dd = np.sum(d * d, axis=-1)  # (T, 1, C)
    w = P[:, :, None] - A  # (T, H, C, 2)
    short = dd < 1e-9  # a vertical capsule is a point on the floor
    dist, s, _ = point_segment_distance_2d(A, B, P[:, :, None])  # (T, H, C)
    closest = A + s[..., None] * d  # (T, H, C, 2)
    i = np.argmin(dist - robot.radii, axis=-1)  # (T, H)
    T, H = P.shape[:2]
    t_idx, h_idx = np.meshgrid(np.arange(T), np.arange(H), indexing="ij")
    s_i = s[t_idx, h_idx, i]
    if not derivatives:
        return NearestBody(
            point=closest[t_idx, h_idx, i], radius=robot.radii[i], d_dq=None, d_dp=None
        )
    d_i = d[t_idx, 0, i]  # (T, H, 2)
    w_i = w[t_idx, h_idx, i]
    dd_i = dd[t_idx, 0, i]
    JA = robot.ends_jacobian[t_idx, i, 0]  # (T, H, 2, n)
    JB = robot.ends_jacobian[t_idx, i, 1]
    Jd = JB - JA
    d_dq = (1 - s_i)[..., None, None] * JA + s_i[..., None, None] * JB
    d_dp = np.zeros((T, H, 2, 2))
    inside = (s_i > 0) & (s_i < 1) & ~short[t_idx, 0, i]
    if np.any(inside):
        inv = 1.0 / np.where(inside, dd_i, 1.0)
        # ∂s/∂q = [d·(−J_A) + w·J_d − 2s d·J_d] / d·d;  ∂s/∂P = dᵀ / d·d.
        ds_dq = (
            -np.einsum("thi,thin->thn", d_i, JA)
            + np.einsum("thi,thin->thn", w_i, Jd)
            - 2 * s_i[..., None] * np.einsum("thi,thin->thn", d_i, Jd)
        ) * inv[..., None]
        ds_dq[~inside] = 0.0
        d_dq += d_i[..., :, None] * ds_dq[..., None, :]
        outer = d_i[..., :, None] * d_i[..., None, :] * inv[..., None, None]
        d_dp = np.where(inside[..., None, None], outer, 0.0)
    return NearestBody(
        point=closest[t_idx, h_idx, i],
        radius=robot.radii[i],
        d_dq=d_dq,
        d_dp=d_dp,
    )


def FloorCapsules(robot, states) -> np.ndarray:
    """(T, C, 2, 2) the ends of every robot capsule's axis on the floor."""
    x = np.asarray(states, dtype=float)
    return robot.CalcKinematics(x[:, : robot.num_positions]).capsule_points[..., :2]


def HumanDistances(robot, states, human_positions, *, capsules=None) -> np.ndarray:
    """(T, H) horizontal distance from each human's centre to the nearest
    robot body (every capsule's surface: the base and every arm link).
    ``capsules``: FloorCapsules(robot, states), if already computed."""
    P = np.asarray(human_positions, dtype=float)  # (T, H, 2)
    if P.size == 0:
        return np.zeros((len(states), 0))
    ends = FloorCapsules(robot, states) if capsules is None else capsules
    d, _, _ = point_segment_distance_2d(
        ends[:, None, :, 0], ends[:, None, :, 1], P[:, :, None, :]
    )  # (T, H, C)
    return np.min(d - robot.capsule_radii[None, None, :], axis=2)


def WallDistances(robot, states, segments, *, capsules=None) -> np.ndarray:
    """(T, S) horizontal distance from each wall segment (S, 2, 2) to the
    nearest robot body's surface (every capsule). ``capsules``:
    FloorCapsules(robot, states), if already computed."""
    W = np.asarray(segments, dtype=float).reshape(-1, 2, 2)
    if W.size == 0:
        return np.zeros((len(states), 0))
    ends = FloorCapsules(robot, states) if capsules is None else capsules
    lift = np.zeros(ends.shape[:-1] + (1,))
    A = np.concatenate([ends[:, None, :, 0], lift[:, None, :, 0]], axis=-1)
    B = np.concatenate([ends[:, None, :, 1], lift[:, None, :, 1]], axis=-1)
    W3 = np.concatenate([W, np.zeros(W.shape[:-1] + (1,))], axis=-1)
    _, _, c1, c2 = segment_closest_points(
        A, B, W3[None, :, None, 0], W3[None, :, None, 1]
    )  # (T, S, C, 3)
    dist = np.linalg.norm((c1 - c2)[..., :2], axis=-1) - robot.capsule_radii
    return dist.min(axis=2)


# The robot as one simulated person sees it (humans/crowd.py, humans/instructed.py).


def NearestBodyOnFloor(position, robot_bodies):
    """The robot capsule nearest to ``position`` on the floor: (the closest
    point on its axis, its radius, its surface distance)."""
    segments, radii = robot_bodies
    a, b = segments[:, 0], segments[:, 1]
    d, s, _ = point_segment_distance_2d(a, b, position)
    closest = a + s[:, None] * (b - a)
    d = d - radii
    i = int(np.argmin(d))
    return closest[i], float(radii[i]), float(d[i])


def RobotAgents(position, robot_position, robot_radius, robot_bodies):
    """The robot as a person at ``position`` sees it, as ORCA agents moving
    with the base: its base and, as a second agent, the nearest of its
    bodies (an arm sticking out is avoided too). Positions (K, 2), radii
    (K,)."""
    robot_p, robot_r = [robot_position], [robot_radius]
    if robot_bodies is not None:
        point, r, _ = NearestBodyOnFloor(position, robot_bodies)
        if np.linalg.norm(point - robot_position) > 1e-6:
            robot_p.append(point)
            robot_r.append(r)
    return np.array(robot_p, dtype=float), np.array(robot_r, dtype=float)


def NearestRobotPoint(position, robot_position, robot_radius, robot_bodies):
    """The robot's point nearest to ``position`` and its radius: the base
    disc's centre, or the nearest body's axis point if that is nearer."""
    if robot_bodies is not None:
        point, r, gap = NearestBodyOnFloor(position, robot_bodies)
        if gap < np.linalg.norm(position - robot_position) - robot_radius:
            return point, r
    return robot_position, robot_radius


def RobotGap(position, radius, robot_position, robot_radius, robot_bodies):
    """Clearance between a person and the nearest robot body (m)."""
    gap = np.linalg.norm(robot_position - position) - robot_radius - radius
    if robot_bodies is not None:
        gap = min(gap, NearestBodyOnFloor(position, robot_bodies)[2] - radius)
    return gap
