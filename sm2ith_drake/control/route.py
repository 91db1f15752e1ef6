"""A route for the base around walls: the manoeuvre out of a spot where
driving at the goal does not get the robot anywhere.

A differential drive with its arm out to one side, stopped beside a door's
jamb and facing the wall, has to back off, turn and come at the door
straight. The MPC's 2 s horizon on the distance to the goal does not see
that manoeuvre, and at a standstill its linearization sees no use in
turning. PlanRoute finds the shortest one for the robot's whole planar
outline, every capsule and the arm included, as the arm is held now.

The search is Dijkstra's over a lattice of base poses: (x, y) on a square
grid and 16 headings, those of the grid steps in ``_STEPS``, so that a step
along any heading lands on a grid point. The moves are:
- a step forward or back along the heading;
- a turn in place to the next heading either way;
- for a holonomic base, a step sideways.

A pose is free when every capsule keeps ``clearance`` from every wall and
every disc (people standing still). A move is free when its two ends and
its middle pose are free. Near the start the robot may be closer than
``clearance`` already (it is stuck against a wall), so there the poses need
only keep what the start keeps.

The recovery (control/recovery.py) drives the route.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from sm2ith_drake.control.tasks import WrapAngle
from sm2ith_drake.geometry import point_segment_distance_2d, segment_closest_points

# The lattice's headings are the directions of these grid steps (lengths 1,
# √2 and √5 cells). Step k + 4 is step k turned by 90°.
_STEPS = np.array(
    [
        (1, 0),
        (2, 1),
        (1, 1),
        (1, 2),
        (0, 1),
        (-1, 2),
        (-1, 1),
        (-2, 1),
        (-1, 0),
        (-2, -1),
        (-1, -1),
        (-1, -2),
        (0, -1),
        (1, -2),
        (1, -1),
        (2, -1),
    ]
)
HEADINGS = np.arctan2(_STEPS[:, 1], _STEPS[:, 0])
NUM_HEADINGS = len(_STEPS)

# How a route's pose i + 1 is reached from pose i.
FORWARD, BACKWARD, TURN, SIDEWAYS = 1, -1, 0, 2

# Within this distance of the start (m) the poses need only keep the
# start's clearance.
START_RADIUS = 0.25
# The lattice checks each capsule against the walls at points this far
# apart along its axis (m), in a distance field of the walls sampled this
# finely (m); against discs it is exact.
SAMPLE_SPACING = 0.03
FIELD_RESOLUTION = 0.01


@dataclass
class Footprint:
    """The robot's planar outline in its base frame (x ahead, y left):
    capsules with axes ``segments`` (C, 2, 2) and radii ``radii`` (C,)."""

    segments: np.ndarray
    radii: np.ndarray


@dataclass
class Route:
    """Base poses (L, 3) from the start (its exact pose) to the goal, the
    move into each pose after the first (L − 1,), and the route's cost
    (metres of travel, back-ups and turns weighted)."""

    poses: np.ndarray
    moves: np.ndarray
    cost: float


def _SegmentDistances(A, B, C, D):
    """Distances between segments A–B and C–D in the plane (broadcast
    arrays (..., 2)), by geometry's closest points (lifted to the floor)."""

    def Lift(x):
        x = np.broadcast_to(x, np.broadcast_shapes(A.shape, C.shape))
        return np.concatenate([x, np.zeros(x.shape[:-1] + (1,))], axis=-1)

    _, _, c1, c2 = segment_closest_points(Lift(A), Lift(B), Lift(C), Lift(D))
    return np.linalg.norm(c1 - c2, axis=-1)


def FootprintClearance(footprint: Footprint, poses, walls, discs=None) -> np.ndarray:
    """(P,) the least distance from the footprint at each base pose (P, 3)
    to the walls (S, 2, 2) and the discs (D, 3: x, y, radius), capsule and
    disc radii subtracted (negative: overlap; +inf with neither)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (P, 2, 2)
    ends = poses[:, None, None, :2] + np.einsum(
        "pij,ckj->pcki", R, np.asarray(footprint.segments, dtype=float)
    )  # (P, C, 2, 2)
    A, B = ends[:, :, None, 0], ends[:, :, None, 1]  # (P, C, 1, 2)
    radii = np.asarray(footprint.radii, dtype=float)[None, :, None]
    out = np.full(len(poses), np.inf)
    walls = np.asarray(walls, dtype=float).reshape(-1, 2, 2)
    if len(walls):
        d = _SegmentDistances(A, B, walls[None, None, :, 0], walls[None, None, :, 1])
        out = np.minimum(out, np.min(d - radii, axis=(1, 2)))
    discs = np.zeros((0, 3)) if discs is None else np.asarray(discs, dtype=float)
    if len(discs):
        d = point_segment_distance_2d(A, B, discs[None, None, :, :2])[0]
        out = np.minimum(out, np.min(d - radii - discs[:, 2], axis=(1, 2)))
    return out


def PlanRoute(
    footprint: Footprint,
    walls,
    start,
    goal,
    *,
    goal_tolerance: float,
    clearance: float,
    discs=None,
    holonomic: bool = False,
    resolution: float = 0.05,
    margin: float = 1.0,
    turn_cost: float = 0.3,
    reverse_cost: float = 1.5,
    max_cells: int = 20000,
) -> Route | None:
    """The cheapest route from the base pose ``start`` (x, y, θ) to within
    ``goal_tolerance`` of the point ``goal``, or None if there is none.

    The lattice covers the box around start and goal grown by ``margin``
    (m), at ``resolution`` (m), with the start on a grid point; at most
    ``max_cells`` grid points (ValueError beyond). Costs: a step its length,
    a step back ``reverse_cost`` times that, a step sideways its length, a
    turn ``turn_cost`` (m per rad) times its angle. ``walls``, ``discs``:
    as in FootprintClearance.
    """
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    if not (np.all(np.isfinite(start)) and np.all(np.isfinite(goal))):
        raise ValueError("PlanRoute needs a finite start and goal")
    h = float(resolution)
    lo = np.minimum(start[:2], goal) - margin
    hi = np.maximum(start[:2], goal) + margin
    below = np.ceil((start[:2] - lo) / h).astype(int)  # start's grid index
    shape = below + np.ceil((hi - start[:2]) / h).astype(int) + 1
    nx, ny = int(shape[0]), int(shape[1])
    if nx * ny > max_cells:
        raise ValueError(f"route lattice of {nx}×{ny} cells exceeds {max_cells}")
    origin = start[:2] - below * h
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    cells = origin + h * np.stack([gx.ravel(), gy.ravel()], axis=1)  # (nx·ny, 2)
    points, radii = _Samples(footprint, SAMPLE_SPACING)
    reach = float(np.max(np.linalg.norm(points, axis=1))) + 2 * FIELD_RESOLUTION
    field = _DistanceField(walls, origin - reach, origin + h * (shape - 1) + reach)
    discs = np.zeros((0, 3)) if discs is None else np.asarray(discs, dtype=float)

    segments = np.asarray(footprint.segments, dtype=float)
    capsule_radii = np.asarray(footprint.radii, dtype=float)

    def Clear(positions, angle):
        c, s = np.cos(angle), np.sin(angle)
        turn = np.array([[c, s], [-s, c]])
        world = positions[:, None, :] + points @ turn
        out = np.min(field(world) - radii, axis=1)
        if len(discs):
            ends = positions[:, None, None, :] + segments @ turn  # (P, C, 2, 2)
            d = point_segment_distance_2d(
                ends[:, :, None, 0], ends[:, :, None, 1], discs[None, None, :, :2]
            )[0]
            d = d - capsule_radii[:, None] - discs[:, 2]
            out = np.minimum(out, np.min(d, axis=(1, 2)))
        return out

    def Clearance(offset, angle):
        return Clear(cells + offset, angle).reshape(nx, ny)

    # The start's own clearance, as the lattice sees it (at its heading).
    start_clear = Clear(start[None, :2], HEADINGS[_Nearest(start[2])])[0]
    near = np.linalg.norm(cells - start[:2], axis=1).reshape(nx, ny) <= START_RADIUS
    need = np.where(near, min(clearance, start_clear), clearance) - 1e-9

    steps = h * _STEPS
    lateral = np.roll(_STEPS, -4, axis=0)  # step k + 4: sideways at heading k
    free = np.stack([Clearance(0.0, a) >= need for a in HEADINGS])  # (K, nx, ny)
    # The turn k → k + 1, at its middle.
    turned = np.stack(
        [
            Clearance(0.0, a + 0.5 * WrapAngle(HEADINGS[(k + 1) % NUM_HEADINGS] - a))
            >= need
            for k, a in enumerate(HEADINGS)
        ]
    )
    node = np.arange(NUM_HEADINGS * nx * ny).reshape(NUM_HEADINGS, nx, ny)
    src, dst, cost = [], [], []

    def Add(k, step, length, valid_middle):
        # Steps from (i, j) to (i + dx, j + dy) at heading k.
        dx, dy = int(step[0]), int(step[1])
        i0, i1 = max(0, -dx), nx - max(0, dx)
        j0, j1 = max(0, -dy), ny - max(0, dy)
        ok = free[k, i0:i1, j0:j1] & free[k, i0 + dx : i1 + dx, j0 + dy : j1 + dy]
        ok &= valid_middle[i0:i1, j0:j1]
        src.append(node[k, i0:i1, j0:j1][ok])
        dst.append(node[k, i0 + dx : i1 + dx, j0 + dy : j1 + dy][ok])
        cost.append(np.full(int(ok.sum()), length))

    for k in range(NUM_HEADINGS):
        a = HEADINGS[k]
        length = float(np.linalg.norm(steps[k]))
        middle = Clearance(0.5 * steps[k], a) >= need
        Add(k, _STEPS[k], length, middle)
        # Back: from the far end of the same step (its middle is the same).
        back_middle = np.zeros((nx, ny), dtype=bool)
        dx, dy = _STEPS[k]
        back_middle[max(0, dx) : nx + min(0, dx), max(0, dy) : ny + min(0, dy)] = (
            middle[max(0, -dx) : nx + min(0, -dx), max(0, -dy) : ny + min(0, -dy)]
        )
        Add(k, -_STEPS[k], reverse_cost * length, back_middle)
        if holonomic:
            for sign in (1, -1):
                side = sign * lateral[k]
                Add(k, side, length, Clearance(0.5 * h * side, a) >= need)
        k1 = (k + 1) % NUM_HEADINGS
        angle = abs(WrapAngle(HEADINGS[k1] - a))
        ok = free[k] & free[k1] & turned[k]
        for s_, d_ in ((node[k], node[k1]), (node[k1], node[k])):
            src.append(s_[ok])
            dst.append(d_[ok])
            cost.append(np.full(int(ok.sum()), turn_cost * angle))

    src, dst = np.concatenate(src), np.concatenate(dst)
    cost = np.concatenate(cost)
    n = node.size
    graph = csr_matrix((cost, (src, dst)), shape=(n, n))
    k0 = _Nearest(start[2])
    first = node[k0, below[0], below[1]]
    dist, pred = dijkstra(graph, directed=True, indices=first, return_predecessors=True)
    at_goal = np.linalg.norm(cells - goal, axis=1).reshape(nx, ny) <= goal_tolerance
    candidates = node[:, at_goal].ravel()
    if not len(candidates) or not np.isfinite(dist[candidates]).any():
        return None
    last = int(candidates[np.argmin(dist[candidates])])
    path = [last]
    while path[-1] != first:
        path.append(int(pred[path[-1]]))
    path = np.array(path[::-1])
    k, i, j = np.unravel_index(path, node.shape)
    poses = np.column_stack([origin[0] + h * i, origin[1] + h * j, HEADINGS[k]])
    # From the start itself (a turn onto the lattice's heading, if it is
    # not on one), headings continuous along the route.
    if abs(WrapAngle(poses[0, 2] - start[2])) > 1e-9:
        poses = np.vstack([start, poses])
    else:
        poses[0] = start
    poses[:, 2] = start[2] + np.concatenate(
        [[0.0], np.cumsum(WrapAngle(np.diff(poses[:, 2])))]
    )
    return Route(poses=poses, moves=_Moves(poses), cost=float(dist[last]))


def _Nearest(angle) -> int:
    """The lattice heading nearest ``angle``."""
    return int(np.argmin(np.abs(WrapAngle(HEADINGS - angle))))


def _Samples(footprint: Footprint, spacing: float):
    """Points (Q, 2) along every capsule's axis at most ``spacing`` apart,
    and their radii (Q,): the capsule's, plus half the spacing, so that the
    least over the points of (distance − radius) is at most the capsule's
    clearance (a distance changes by at most the distance moved)."""
    points, radii = [], []
    segments = np.asarray(footprint.segments, dtype=float)
    for (a, b), r in zip(segments, footprint.radii, strict=True):
        count = int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1
        t = np.linspace(0.0, 1.0, count)[:, None]
        points.append(a + t * (b - a))
        radii.append(np.full(count, r + (0.5 * spacing if count > 1 else 0.0)))
    return np.concatenate(points), np.concatenate(radii)


def _DistanceField(walls, lo, hi):
    """The distance to the nearest wall, sampled every FIELD_RESOLUTION over
    the box lo–hi and read at the nearest sample: a function of points
    (..., 2) inside the box, +inf without walls. A point is at most
    FIELD_RESOLUTION / √2 from its sample and the distance is 1-Lipschitz,
    so that much is subtracted: never an overestimate."""
    walls = np.asarray(walls, dtype=float).reshape(-1, 2, 2)
    if not len(walls):
        return lambda p: np.full(np.shape(p)[:-1], np.inf)
    h = FIELD_RESOLUTION
    n = np.ceil((np.asarray(hi) - lo) / h).astype(int) + 1
    gx, gy = np.meshgrid(np.arange(n[0]), np.arange(n[1]), indexing="ij")
    grid = lo + h * np.stack([gx, gy], axis=-1)  # (nx, ny, 2)
    d = point_segment_distance_2d(walls[:, 0], walls[:, 1], grid[..., None, :])[0]
    table = np.min(d, axis=-1) - h / np.sqrt(2.0)

    def Field(p):
        index = np.rint((np.asarray(p) - lo) / h).astype(int)
        i = np.clip(index[..., 0], 0, n[0] - 1)
        j = np.clip(index[..., 1], 0, n[1] - 1)
        return table[i, j]

    return Field


def _Moves(poses):
    """The move into each pose after the first (lattice moves change either
    the position or the heading)."""
    d = np.diff(poses[:, :2], axis=0)
    ahead = np.cos(poses[:-1, 2]) * d[:, 0] + np.sin(poses[:-1, 2]) * d[:, 1]
    aside = -np.sin(poses[:-1, 2]) * d[:, 0] + np.cos(poses[:-1, 2]) * d[:, 1]
    moves = np.where(ahead > 0, FORWARD, BACKWARD)
    moves = np.where(np.abs(aside) > np.abs(ahead), SIDEWAYS, moves)
    return np.where(np.linalg.norm(d, axis=1) < 1e-9, TURN, moves)
