"""A standalone, exact solver of one human's relaxed-ORCA QP
(eq. relaxed_orca_acc_argmin), with its KKT multipliers.

    min_{a, ζ}  ‖a − v_pref‖² + M_a ζ_a² + M_v ‖ζ_v‖²
    s.t.        ‖a‖² ≤ a_max²                               (λ_s)
                ‖a − v_t‖² ≤ (Δt·acc_max)² + ζ_a            (λ_a)
                n_iᵀa ≥ ρ_i − ζ_v,i   (agent lines)         (λ_i)
                n_oᵀa ≥ ρ_o           (static lines)        (λ_o)
                ζ ≥ 0                                       (μ)

The slacks enter quadratically, so at the optimum ζ_a = max(0, ‖a − v_t‖² −
(Δt·acc_max)²) and ζ_v,i = max(0, ρ_i − n_iᵀa): the problem reduces to
minimizing a convex, continuously differentiable f(a) in the plane over the
speed disc and the static half-planes. Stationarity in ζ then gives
λ_a = 2M_a ζ_a, λ_i = 2M_v ζ_v,i and μ = 0 exactly, and λ_s, λ_o follow from
stationarity in a by non-negative least squares on the active set.

This is the oracle of the KKT embedding (humans/orca_kkt.py) and the warm
start of its multipliers.
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, nnls

_ACTIVE_TOL = 1e-7


@dataclass
class RelaxedOrcaSolution:
    velocity: np.ndarray  # a (2,)
    slack_acceleration: float  # ζ_a
    slack_velocity: np.ndarray  # ζ_v (A,)
    multiplier_speed: float  # λ_s
    multiplier_acceleration: float  # λ_a
    multipliers_agents: np.ndarray  # λ_i (A,)
    multipliers_static: np.ndarray  # λ_o (S,)
    multiplier_slack_acceleration: float  # μ_a
    multipliers_slack_velocity: np.ndarray  # μ_v (A,)
    cost: float
    stationarity_residual: float


def _Reduced(a, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv):
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


def relaxed_orca_action(
    v_pref,
    v_current,
    normals,
    offsets,
    *,
    max_speed,
    max_accel,
    time_step,
    slack_weights,
    static_normals=None,
    static_offsets=None,
) -> RelaxedOrcaSolution:
    """Solves one human's relaxed-ORCA QP exactly (see the module doc).

    Args:
        v_pref: preferred velocity (2,).
        v_current: current velocity v_t (2,).
        normals, offsets: agent half-planes n_iᵀa ≥ ρ_i, (A, 2) and (A,).
        max_speed, max_accel, time_step: a_max, acc_max, Δt.
        slack_weights: (M_a, M_v).
        static_normals, static_offsets: static half-planes (S, 2), (S,).
    """
    v_pref = np.asarray(v_pref, dtype=float)
    v_t = np.asarray(v_current, dtype=float)
    n = np.asarray(normals, dtype=float).reshape(-1, 2)
    rho = np.asarray(offsets, dtype=float).reshape(-1)
    no = (
        np.zeros((0, 2))
        if static_normals is None
        else np.asarray(static_normals, dtype=float).reshape(-1, 2)
    )
    rho_o = (
        np.zeros(0)
        if static_offsets is None
        else np.asarray(static_offsets, dtype=float).reshape(-1)
    )
    Ma, Mv = (float(w) for w in slack_weights)
    r_acc_sq = (time_step * max_accel) ** 2
    vmax_sq = max_speed**2

    def feasible(a):
        return a @ a <= vmax_sq + 1e-12 and np.all(no @ a >= rho_o - 1e-10)

    # Damped Newton on the unconstrained reduced problem.
    a = v_pref.copy()
    for _ in range(50):
        f, g, Hm = _Reduced(a, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)
        step = -np.linalg.solve(Hm, g)
        t = 1.0
        while t > 1e-8:
            trial = a + t * step
            if _Reduced(trial, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[
                0
            ] <= f + 1e-4 * t * (g @ step):
                break
            t *= 0.5
        a = a + t * step
        if np.linalg.norm(t * step) < 1e-13:
            break
    if not feasible(a):
        # Constrained: SLSQP on the (smooth, convex) reduced problem.
        cons = [
            {"type": "ineq", "fun": lambda x: vmax_sq - x @ x, "jac": lambda x: -2 * x}
        ]
        for i in range(len(rho_o)):
            cons.append(
                {
                    "type": "ineq",
                    "fun": lambda x, i=i: no[i] @ x - rho_o[i],
                    "jac": lambda x, i=i: no[i],
                }
            )
        start = a * min(1.0, max_speed / max(np.linalg.norm(a), 1e-12)) * 0.999
        res = minimize(
            lambda x: _Reduced(x, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[0],
            start,
            jac=lambda x: _Reduced(x, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[1],
            constraints=cons,
            method="SLSQP",
            options={"ftol": 1e-14, "maxiter": 200},
        )
        a = res.x
    e = a - v_t
    za = max(0.0, e @ e - r_acc_sq)
    zv = np.maximum(0.0, rho - n @ a)
    lam_a = 2 * Ma * za
    lam_i = 2 * Mv * zv
    # Stationarity in a: 2(a − v_pref) + 2λ_a e − Σλ_i n_i + 2λ_s a − Σλ_o n_o = 0.
    r = 2 * (a - v_pref) + 2 * lam_a * e - n.T @ lam_i
    cols, which = [], []
    if a @ a >= vmax_sq - 1e-6:
        cols.append(2 * a)
        which.append(-1)
    for o in range(len(rho_o)):
        if no[o] @ a - rho_o[o] <= 1e-6:
            cols.append(-no[o])
            which.append(o)
    lam_s, lam_o = 0.0, np.zeros(len(rho_o))
    if cols:
        sol, _ = nnls(np.column_stack(cols), -r)
        for w, value in zip(which, sol, strict=True):
            if w < 0:
                lam_s = float(value)
            else:
                lam_o[w] = value
    resid = r + 2 * lam_s * a - no.T @ lam_o
    f = _Reduced(a, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[0]
    return RelaxedOrcaSolution(
        velocity=a,
        slack_acceleration=za,
        slack_velocity=zv,
        multiplier_speed=lam_s,
        multiplier_acceleration=lam_a,
        multipliers_agents=lam_i,
        multipliers_static=lam_o,
        multiplier_slack_acceleration=0.0,
        multipliers_slack_velocity=np.zeros(len(rho)),
        cost=float(f),
        stationarity_residual=float(np.linalg.norm(resid)),
    )
