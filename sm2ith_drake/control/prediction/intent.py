"""Where a person means to go, near walls: the ORCA model's preferred
velocity v_pref turned toward the nearest free direction.

The paper gives each person "some given desired velocity (e.g. latest
measured human velocity)". Next to a wall that guess says the person means
to walk into the wall: a person heading for a door a little off its centre
is predicted to stop against the wall beside it, and stay there. People
steer for openings. So a v_pref whose straight line (over the look-ahead,
at the person's speed, with the person's radius) runs into a wall is turned,
by the smallest angle on either side, onto the nearest line that does not;
its speed is kept. A v_pref whose every direction is blocked within the
turn limit, or that already runs free, is left as it is.
"""

import numpy as np

from sm2ith_drake.geometry import point_segment_distance_2d, segment_closest_points

# Turns tried (rad), smallest first, alternating sides.
_STEP = np.deg2rad(5.0)


def SteerAroundWalls(
    positions,
    v_pref,
    segments,
    radius: float,
    *,
    lookahead: float,
    max_turn: float = np.deg2rad(90.0),
    min_speed: float = 0.05,
) -> np.ndarray:
    """Each person's v_pref turned off the walls (see the module).

    Args:
        positions, v_pref: (H, 2) positions and preferred velocities.
        segments: (S, 2, 2) wall segments.
        radius: the people's radius (m).
        lookahead: how far ahead a line must run free (s, at the person's
            preferred speed).
        max_turn: the largest turn tried (rad).
        min_speed: people slower than this (m/s) keep their v_pref.

    Returns:
        (H, 2) preferred velocities. A line runs free when it never comes
        nearer to a wall than the radius, or than the person already is,
        whichever is less (a person already against a wall may walk along
        it).
    """
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    out = np.array(v_pref, dtype=float).reshape(-1, 2)
    segments = np.asarray(segments, dtype=float).reshape(-1, 2, 2)
    if not len(segments) or not len(out):
        return out
    k = int(np.floor(max_turn / _STEP + 1e-9))
    turns = np.concatenate([[0.0], np.ravel([[i, -i] for i in range(1, k + 1)])])
    turns = turns * _STEP
    c, s = np.cos(turns), np.sin(turns)
    for j, (p, v) in enumerate(zip(positions, out, strict=True)):
        speed = float(np.linalg.norm(v))
        if not np.all(np.isfinite(p)) or not np.isfinite(speed) or speed < min_speed:
            continue
        u = v / speed
        # (T, 2) candidate directions, rotated by each turn.
        dirs = np.stack([c * u[0] - s * u[1], s * u[0] + c * u[1]], axis=1)
        ends = p + speed * lookahead * dirs
        # Clearance of each candidate line to each wall (T, S).
        _, _, c1, c2 = segment_closest_points(
            np.broadcast_to(p, (len(turns), len(segments), 2)),
            ends[:, None, :],
            segments[None, :, 0, :],
            segments[None, :, 1, :],
        )
        clearance = np.linalg.norm(c1 - c2, axis=-1)
        now, _, _ = point_segment_distance_2d(segments[:, 0], segments[:, 1], p)
        needed = np.minimum(radius, now) - 1e-6
        free = np.all(clearance >= needed[None, :], axis=1)
        if free[0] or not np.any(free):
            continue
        out[j] = speed * dirs[int(np.argmax(free))]
    return out
