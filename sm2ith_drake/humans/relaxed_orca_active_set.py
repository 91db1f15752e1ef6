"""The relaxed-ORCA QP's reduced problem (humans/relaxed_orca.py: f(a),
convex and continuously differentiable in the plane) and its exact
minimizer over the speed disc and the static half-planes by active sets.

When f's unconstrained minimizer leaves the feasible set, the minimizer
lies on its boundary with one or two constraints active. For each
candidate set (the violated constraints first) Newton's method on the
KKT system of those constraints, held with equality, finds the candidate
point; the first that is feasible, stationary and has non-negative
multipliers is a KKT point of a strictly convex problem, hence the
minimizer. This replaced SLSQP as the first resort (~5 ms a call, most of
the people's QP time in steps near walls or at the speed limit); SLSQP
stays the fallback.
"""

import numpy as np


def Reduced(a, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv):
    """f(a), its gradient and a (generalized) Hessian."""
    d = a - v_pref
    e = a - v_t
    za = max(0.0, e @ e - r_acc_sq)
    zv = np.maximum(0.0, rho - n @ a)
    f = d @ d + Ma * za**2 + Mv * zv @ zv
    g = 2 * d + 4 * Ma * za * e - 2 * Mv * n.T @ zv
    Hm = 2 * np.eye(2) + 2 * Mv * (n[zv > 0].T @ n[zv > 0])
    if za > 0:
        Hm += 4 * Ma * (za * np.eye(2) + 2 * np.outer(e, e))
    return f, g, Hm


def _Constraint(x, w, no, rho_o, vmax_sq):
    """Constraint w (−1: the speed disc, else static line w) as h(x) ≤ 0:
    (h, ∇h) with h_s = ‖x‖² − a_max², h_o = ρ_o − n_oᵀx."""
    if w < 0:
        return x @ x - vmax_sq, 2 * x
    return rho_o[w] - no[w] @ x, -no[w]


def _KktNewton(x, active, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv):
    """Newton on the KKT system of f with the constraints ``active`` held
    with equality, from x. Returns (x, λ), or None if a KKT matrix is
    singular."""
    lam = np.zeros(len(active))
    for _ in range(20):
        _, g, Hm = Reduced(x, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)
        rows = [_Constraint(x, w, no, rho_o, vmax_sq) for w in active]
        J = np.array([row[1] for row in rows])
        h = np.array([row[0] for row in rows])
        for j, w in enumerate(active):
            if w < 0:
                Hm = Hm + 2 * lam[j] * np.eye(2)
        K = np.zeros((2 + len(active), 2 + len(active)))
        K[:2, :2], K[:2, 2:], K[2:, :2] = Hm, J.T, J
        try:
            sol = np.linalg.solve(K, -np.concatenate([g, h]))
        except np.linalg.LinAlgError:
            return None
        x, lam = x + sol[:2], sol[2:]
        if np.linalg.norm(sol[:2]) < 1e-15:
            break
    return x, lam


def PolishActiveSet(a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv):
    """Newton on the KKT system of the constraints active at a (speed disc
    ‖a‖² = a_max², static lines n_oᵀa = ρ_o), dropping a constraint whose
    multiplier turns negative. Returns None if it does not settle."""
    active = ([-1] if a @ a >= vmax_sq - 1e-6 else []) + [
        o for o in range(len(rho_o)) if no[o] @ a - rho_o[o] <= 1e-6
    ]
    args = (v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv)
    while 0 < len(active) <= 2:
        out = _KktNewton(a.copy(), active, *args)
        if out is None:
            return None
        x, lam = out
        if np.all(lam >= -1e-12):
            return x
        del active[int(np.argmin(lam))]
    return None


def _Starts(a, active, no, rho_o, vmax_sq):
    """Points on the boundary pieces ``active`` (one or two constraints)
    near the unconstrained minimizer a, to start _KktNewton from."""
    vmax = np.sqrt(vmax_sq)
    lines = [w for w in active if w >= 0]
    if len(lines) == 2:  # two lines: their intersection
        M = np.array([no[lines[0]], no[lines[1]]])
        if abs(np.linalg.det(M)) < 1e-12:
            return []
        return [np.linalg.solve(M, rho_o[lines])]
    if not lines:  # the speed circle
        return [a * vmax / max(np.linalg.norm(a), 1e-12)]
    w = lines[0]
    nn = no[w] / max(np.linalg.norm(no[w]), 1e-12)
    offset = rho_o[w] / max(np.linalg.norm(no[w]), 1e-12)
    foot = a - (nn @ a - offset) * nn  # a projected onto the line
    if len(active) == 1:
        return [foot]
    # The line and the circle: their intersections, the nearer to a first.
    along = np.array([-nn[1], nn[0]])
    base = offset * nn
    half = vmax_sq - offset**2
    if half < 0:
        return []
    t = np.sqrt(half)
    points = [base + t * along, base - t * along]
    return sorted(points, key=lambda p: np.linalg.norm(p - a))


def ActiveSetMinimum(a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv):
    """The constrained minimizer of the convex f over the speed disc and the
    static half-planes, for an unconstrained minimizer a outside them: a
    KKT point (feasible, λ ≥ 0, stationary) on one or two active
    constraints, tried the violated ones first. f is strictly convex, so a
    KKT point is the minimizer. None if no candidate set gives one (the
    caller falls back to SLSQP)."""
    args = (v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv)
    every = [-1, *range(len(rho_o))]
    violated = [w for w in every if _Constraint(a, w, no, rho_o, vmax_sq)[0] > 0]
    rest = [w for w in every if w not in violated]
    order = violated + rest
    sets = [[w] for w in order] + [
        [order[i], order[j]]
        for i in range(len(order))
        for j in range(i + 1, len(order))
    ]
    for active in sets:
        for start in _Starts(a, active, no, rho_o, vmax_sq):
            out = _KktNewton(start, active, *args)
            if out is None:
                continue
            x, lam = out
            if not np.all(np.isfinite(x)) or np.any(lam < -1e-12):
                continue
            g = Reduced(x, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[1]
            rows = [_Constraint(x, w, no, rho_o, vmax_sq) for w in active]
            stationarity = g + sum(l * row[1] for l, row in zip(lam, rows, strict=True))
            if (
                max(abs(row[0]) for row in rows) < 1e-9
                and np.linalg.norm(stationarity) < 1e-8 * (1 + np.linalg.norm(g))
                and x @ x <= vmax_sq + 1e-12
                and np.all(no @ x >= rho_o - 1e-10)
            ):
                return x
    return None
