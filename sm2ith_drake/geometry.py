"""Capsule geometry for collision constraints, vectorized over many pairs.

A capsule is a segment swept by a sphere; the signed distance between two
capsules is the distance between their segments minus both radii. Its
gradient follows from the closest points (the envelope theorem: the
closest-point parameters may be held fixed while differentiating).
"""

import numpy as np

_EPS = 1e-12
# Guards the point–segment division (degenerate segments only).
_EPS_SEGMENT = 1e-9


def einsum(subscripts: str, *operands) -> np.ndarray:
    """np.einsum, except that a contraction over an empty axis is exactly
    zero. Measured here (numpy 2.5.5): ``np.einsum("kho,khod->khd", x, y)``
    with an empty o axis (a scene without static lines) returned values
    from uninitialized memory, NaN in some runs and not in others, so a
    plan depended on what the process had run before. Explicit subscripts
    without ellipsis only."""
    operands = [np.asarray(op) for op in operands]
    if all(op.size for op in operands):
        return np.einsum(subscripts, *operands)
    inputs, output = subscripts.split("->")
    sizes = {}
    for letters, op in zip(inputs.split(","), operands, strict=True):
        sizes.update(zip(letters, op.shape, strict=True))
    return np.zeros(tuple(sizes[c] for c in output))


def segment_closest_points(p1, q1, p2, q2):
    """Closest points of segments p1–q1 and p2–q2 (arrays (..., 3)).

    Returns (s, t, c1, c2) with c1 = p1 + s (q1 − p1), c2 = p2 + t (q2 − p2),
    s, t ∈ [0, 1] (Ericson, Real-Time Collision Detection, 5.1.9, vectorized;
    degenerate segments are points).
    """
    p1, q1, p2, q2 = (np.asarray(a, dtype=float) for a in (p1, q1, p2, q2))
    d1, d2 = q1 - p1, q2 - p2
    r = p1 - p2
    a = np.sum(d1 * d1, axis=-1)
    e = np.sum(d2 * d2, axis=-1)
    f = np.sum(d2 * r, axis=-1)
    c = np.sum(d1 * r, axis=-1)
    b = np.sum(d1 * d2, axis=-1)
    denom = a * e - b * b
    safe_a = np.where(a > _EPS, a, 1.0)
    safe_e = np.where(e > _EPS, e, 1.0)
    # General case: s from the infinite lines (clamped), then t from s.
    s = np.where(
        denom > _EPS * np.maximum(a * e, _EPS),
        np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0, 1),
        0.0,
    )
    t = (b * s + f) / safe_e
    # t outside [0, 1]: clamp it and recompute s.
    s = np.where(t < 0, np.clip(-c / safe_a, 0, 1), s)
    s = np.where(t > 1, np.clip((b - c) / safe_a, 0, 1), s)
    t = np.clip(t, 0, 1)
    # Degenerate segments.
    point1, point2 = a <= _EPS, e <= _EPS
    s = np.where(point1, 0.0, s)
    t = np.where(point1 & ~point2, np.clip(f / safe_e, 0, 1), t)
    s = np.where(point2 & ~point1, np.clip(-c / safe_a, 0, 1), s)
    t = np.where(point2, 0.0, t)
    c1 = p1 + s[..., None] * d1
    c2 = p2 + t[..., None] * d2
    return s, t, c1, c2


def capsule_pair_distance_and_gradient(points1, jac1, r1, points2, jac2, r2):
    """Signed capsule distances and their gradients w.r.t. q.

    Args:
        points1, points2: (..., 2, 3) segment endpoints.
        jac1, jac2: (..., 2, 3, n) endpoint Jacobians (``jac2`` may be None
            for a capsule that does not depend on q).
        r1, r2: radii (broadcastable to the leading shape).

    Returns:
        d (...,) and grad (..., n).
    """
    s, t, c1, c2 = segment_closest_points(
        points1[..., 0, :], points1[..., 1, :], points2[..., 0, :], points2[..., 1, :]
    )
    diff = c1 - c2
    dist = np.linalg.norm(diff, axis=-1)
    normal = diff / np.maximum(dist, _EPS)[..., None]
    J1 = (1 - s)[..., None, None] * jac1[..., 0, :, :] + s[..., None, None] * jac1[
        ..., 1, :, :
    ]
    Jrel = J1
    if jac2 is not None:
        J2 = (1 - t)[..., None, None] * jac2[..., 0, :, :] + t[..., None, None] * jac2[
            ..., 1, :, :
        ]
        Jrel = J1 - J2
    grad = np.einsum("...i,...in->...n", normal, Jrel)
    return dist - r1 - r2, grad


def capsule_distance_and_gradient(robot, kin, pairs):
    """Self-collision distances of capsule ``pairs`` at every knot.

    Args:
        robot: a MobileManipulator (for the radii).
        kin: its Kinematics at K configurations.
        pairs: list of (i, j) capsule indices.

    Returns:
        d (K, P) and grad (K, P, n).
    """
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    i, j = pairs[:, 0], pairs[:, 1]
    P, J = kin.capsule_points, kin.capsule_jacobians
    radii = robot.capsule_radii
    return capsule_pair_distance_and_gradient(
        P[:, i], J[:, i], radii[i], P[:, j], J[:, j], radii[j]
    )


def point_segment_distance_2d(A, B, P):
    """Distances from points P to segments A–B in the plane (arrays (..., 2)).

    Returns (d, s, n): the distance, the closest-point parameter on the
    segment and the unit vector from P to the closest point.
    """
    AB = B - A
    denom = np.maximum(np.sum(AB * AB, axis=-1), _EPS_SEGMENT)
    s = np.clip(np.sum((P - A) * AB, axis=-1) / denom, 0.0, 1.0)
    c = A + s[..., None] * AB
    diff = c - P
    d = np.linalg.norm(diff, axis=-1)
    n = diff / np.maximum(d, _EPS_SEGMENT)[..., None]
    return d, s, n
