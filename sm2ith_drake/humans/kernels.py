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


def Compile() -> None:
    """Compiles (or loads from the cache) every kernel, so that no control
    step pays for it."""
    one = np.ones((1, 2))
    agent_lines(one, one, np.ones(1), 2.0, 0.1, np.empty((1, 2)), np.empty((1, 2)))
    relaxed_orca_newton(one, one, np.ones((1, 1, 2)), np.ones((1, 1)), 0.1, 1.0, 1.0)
