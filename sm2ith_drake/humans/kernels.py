"""Compiled (numba) inner loops of the people's ORCA model: the agent lines
of many pairs, and the damped Newton of many relaxed-ORCA QPs.

Both run once per person, line and step of every forward simulation, for a
few people and lines at a time, where numpy's per-call overhead was most of
the cost (with 3 people: 0.5 ms per batched numpy call, ~10 ms per forward
simulation of 10 steps). The numpy wrappers that broadcast, reshape and
document them are :func:`sm2ith_drake.humans.orca.orca_agent_lines` and
:func:`sm2ith_drake.humans.relaxed_orca.relaxed_orca_actions`.

``cache=True`` keeps the machine code next to this file, so only the first
process on a machine compiles (a few seconds); :func:`Compile` does it
ahead of a controller's first step.
"""

import math

import numba
import numpy as np

# point_segment_distance_2d's guard (a point-like segment), for the same
# arithmetic.
from sm2ith_drake.geometry import _EPS_SEGMENT

# Guards divisions in the agent lines (degenerate geometry only).
_EPS = 1e-9
# Relative resolution of f: a smaller Armijo decrease is roundoff.
_ROUNDOFF = 1e-14


@numba.njit(cache=True)
def agent_lines(P, V, R, tau, time_step, u, direction):  # pragma: no cover
    """ORCA's u and line direction of M agent pairs (RVO2's
    Agent::computeNewVelocity, agent part): rows of P (M, 2) relative
    positions, V (M, 2) relative velocities, R (M,) combined radii; writes
    u (M, 2) and direction (M, 2)."""
    for i in range(P.shape[0]):
        px, py = P[i, 0], P[i, 1]
        vx, vy = V[i, 0], V[i, 1]
        r = R[i]
        dist_sq = px * px + py * py
        r_sq = r * r
        if dist_sq <= r_sq:
            # Collision: the cutoff circle of the time step.
            wx, wy = vx - px / time_step, vy - py / time_step
            w_len = math.sqrt(max(wx * wx + wy * wy, _EPS))
            ux, uy = wx / w_len, wy / w_len
            direction[i, 0], direction[i, 1] = uy, -ux
            scale = r / time_step - w_len
            u[i, 0], u[i, 1] = scale * ux, scale * uy
            continue
        wx, wy = vx - px / tau, vy - py / tau
        w_len_sq = wx * wx + wy * wy
        dot1 = wx * px + wy * py
        if dot1 < 0.0 and dot1 * dot1 > r_sq * w_len_sq:
            # The cutoff circle.
            w_len = math.sqrt(max(w_len_sq, _EPS))
            ux, uy = wx / w_len, wy / w_len
            direction[i, 0], direction[i, 1] = uy, -ux
            scale = r / tau - w_len
            u[i, 0], u[i, 1] = scale * ux, scale * uy
            continue
        # A leg of the cone.
        leg = math.sqrt(max(dist_sq - r_sq, 0.0))
        safe = max(dist_sq, _EPS)
        if px * wy - py * wx > 0.0:
            dx = (px * leg - py * r) / safe
            dy = (px * r + py * leg) / safe
        else:
            dx = -(px * leg + py * r) / safe
            dy = -(-px * r + py * leg) / safe
        dot2 = vx * dx + vy * dy
        direction[i, 0], direction[i, 1] = dx, dy
        u[i, 0], u[i, 1] = dot2 * dx - vx, dot2 * dy - vy


@numba.njit(cache=True)
def _ReducedCost(ax, ay, pref, vt, n, rho, r_acc_sq, Ma, Mv):  # pragma: no cover
    ex, ey = ax - vt[0], ay - vt[1]
    za = max(0.0, ex * ex + ey * ey - r_acc_sq)
    dx, dy = ax - pref[0], ay - pref[1]
    f = dx * dx + dy * dy + Ma * za * za
    for i in range(n.shape[0]):
        zv = max(0.0, rho[i] - n[i, 0] * ax - n[i, 1] * ay)
        f += Mv * zv * zv
    return f


@numba.njit(cache=True)
def relaxed_orca_newton(v_pref, v_t, n, rho, r_acc_sq, Ma, Mv):  # pragma: no cover
    """The unconstrained minimizers a (B, 2) of the reduced relaxed-ORCA
    costs f(a) (relaxed_orca.py) of B instances: damped Newton with Armijo
    backtracking, from a = v_pref, at most 50 steps."""
    B, A = n.shape[0], n.shape[1]
    out = np.empty((B, 2))
    for b in range(B):
        pref, vt, nb, rb = v_pref[b], v_t[b], n[b], rho[b]
        ax, ay = pref[0], pref[1]
        for _ in range(50):
            ex, ey = ax - vt[0], ay - vt[1]
            za = max(0.0, ex * ex + ey * ey - r_acc_sq)
            f = _ReducedCost(ax, ay, pref, vt, nb, rb, r_acc_sq, Ma, Mv)
            gx = 2 * (ax - pref[0]) + 4 * Ma * za * ex
            gy = 2 * (ay - pref[1]) + 4 * Ma * za * ey
            h11 = h22 = 2 + 4 * Ma * za
            h12 = 0.0
            for i in range(A):
                zv = max(0.0, rb[i] - nb[i, 0] * ax - nb[i, 1] * ay)
                gx -= 2 * Mv * zv * nb[i, 0]
                gy -= 2 * Mv * zv * nb[i, 1]
                if zv > 0:
                    h11 += 2 * Mv * nb[i, 0] * nb[i, 0]
                    h12 += 2 * Mv * nb[i, 0] * nb[i, 1]
                    h22 += 2 * Mv * nb[i, 1] * nb[i, 1]
            if za > 0:
                h11 += 8 * Ma * ex * ex
                h12 += 8 * Ma * ex * ey
                h22 += 8 * Ma * ey * ey
            scale = -1.0 / (h11 * h22 - h12 * h12)
            sx = scale * (h22 * gx - h12 * gy)
            sy = scale * (h11 * gy - h12 * gx)
            t = 1.0
            slope = 1e-4 * (gx * sx + gy * sy)
            allowance = _ROUNDOFF * (1 + abs(f))
            while t > 1e-8:
                trial = _ReducedCost(
                    ax + t * sx, ay + t * sy, pref, vt, nb, rb, r_acc_sq, Ma, Mv
                )
                if trial <= f + t * slope + allowance:
                    break
                t *= 0.5
            sx, sy = t * sx, t * sy
            ax, ay = ax + sx, ay + sy
            if sx * sx + sy * sy < 1e-26:
                break
        out[b, 0], out[b, 1] = ax, ay
    return out


@numba.njit(cache=True)
def _SegmentPoint(ax, ay, bx, by, px, py):  # pragma: no cover
    """geometry.point_segment_distance_2d for one point and segment, with
    the same arithmetic: (distance, closest x, closest y)."""
    dx, dy = bx - ax, by - ay
    denom = max(dx * dx + dy * dy, _EPS_SEGMENT)
    s = min(max(((px - ax) * dx + (py - ay) * dy) / denom, 0.0), 1.0)
    cx, cy = ax + s * dx, ay + s * dy
    ex, ey = cx - px, cy - py
    return math.sqrt(ex * ex + ey * ey), cx, cy


@numba.njit(cache=True)
def step_half_planes(  # pragma: no cover
    P,
    V,
    neighbors,
    robot_p,
    robot_v,
    ends,
    capsule_radii,
    radius,
    share,
    segments,
    human_radius,
    tau,
    time_step,
    tau_obs,
    n,
    rho,
    no,
    rho_o,
):
    """The half-planes of H people at one step of a forward simulation
    (OrcaModel.HalfPlanes with T = 1, the same arithmetic): positions P and
    velocities V (H, 2), neighbours (H, K); the robot's base position and
    world velocity (2,), its capsules' floor axes ends (C, 2, 2) and radii
    (C,); the lines' combined radii (A,) (the last is set here from the
    nearest body) and shares (H, A); wall segments (S, 2, 2). Writes agent
    lines n (H, A, 2), ρ (H, A) and static lines no (H, S, 2), ρ_o (H, S)."""
    H, K = neighbors.shape
    A = K + 2
    rel_p = np.empty((H * A, 2))
    rel_v = np.empty((H * A, 2))
    R = np.empty(H * A)
    for h in range(H):
        px, py = P[h, 0], P[h, 1]
        vx, vy = V[h, 0], V[h, 1]
        # The nearest capsule (surface distance; the first of equals).
        best, bx, by, br = np.inf, 0.0, 0.0, 0.0
        for c in range(ends.shape[0]):
            d, cx, cy = _SegmentPoint(
                ends[c, 0, 0], ends[c, 0, 1], ends[c, 1, 0], ends[c, 1, 1], px, py
            )
            if d - capsule_radii[c] < best:
                best, bx, by, br = d - capsule_radii[c], cx, cy, capsule_radii[c]
        for a in range(A):
            i = h * A + a
            R[i] = radius[a]
            if a < K:
                j = neighbors[h, a]
                ox, oy, ovx, ovy = P[j, 0], P[j, 1], V[j, 0], V[j, 1]
            elif a == K:
                ox, oy, ovx, ovy = robot_p[0], robot_p[1], robot_v[0], robot_v[1]
            else:
                ox, oy, ovx, ovy = bx, by, robot_v[0], robot_v[1]
                R[i] = human_radius + br
            rel_p[i, 0], rel_p[i, 1] = ox - px, oy - py
            rel_v[i, 0], rel_v[i, 1] = vx - ovx, vy - ovy
        for s in range(segments.shape[0]):
            d, cx, cy = _SegmentPoint(
                segments[s, 0, 0],
                segments[s, 0, 1],
                segments[s, 1, 0],
                segments[s, 1, 1],
                px,
                py,
            )
            m = max(d, _EPS_SEGMENT)
            no[h, s, 0] = -((cx - px) / m)
            no[h, s, 1] = -((cy - py) / m)
            rho_o[h, s] = -(d - human_radius) / tau_obs
    u = np.empty((H * A, 2))
    direction = np.empty((H * A, 2))
    agent_lines(rel_p, rel_v, R, tau, time_step, u, direction)
    for h in range(H):
        for a in range(A):
            i = h * A + a
            nx, ny = -direction[i, 1], direction[i, 0]
            ptx = V[h, 0] + share[h, a] * u[i, 0]
            pty = V[h, 1] + share[h, a] * u[i, 1]
            n[h, a, 0], n[h, a, 1] = nx, ny
            rho[h, a] = nx * ptx + ny * pty


def Compile() -> None:
    """Compiles (or loads from the cache) every kernel, so that no control
    step pays for it."""
    one = np.ones((1, 2))
    agent_lines(one, one, np.ones(1), 2.0, 0.1, np.empty((1, 2)), np.empty((1, 2)))
    relaxed_orca_newton(one, one, np.ones((1, 1, 2)), np.ones((1, 1)), 0.1, 1.0, 1.0)
    step_half_planes(
        one,
        one,
        np.zeros((1, 0), dtype=np.int64),
        one[0],
        one[0],
        np.zeros((1, 2, 2)),
        np.ones(1),
        np.ones(2),
        np.ones((1, 2)),
        np.zeros((0, 2, 2)),
        0.3,
        2.0,
        0.1,
        0.5,
        np.empty((1, 2, 2)),
        np.empty((1, 2)),
        np.empty((1, 0, 2)),
        np.empty((1, 0)),
    )
