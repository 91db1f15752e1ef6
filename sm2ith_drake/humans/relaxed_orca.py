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

relaxed_orca_actions solves many instances (one per human) at once: the same
Newton on f, vectorized over the instances; the rare instances whose
unconstrained minimizer leaves the speed disc or a static half-plane are
finished by relaxed_orca_action.

This is the oracle of the KKT embedding (humans/orca_kkt.py) and the warm
start of its multipliers.
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, nnls

from sm2ith_drake.geometry import einsum
from sm2ith_drake.humans.kernels import relaxed_orca_newton
from sm2ith_drake.humans.relaxed_orca_active_set import (
    ActiveSetMinimum,
    PolishActiveSet,
    Reduced,
)

_ACTIVE_TOL = 1e-7
# Relative resolution of f: a smaller Armijo decrease is roundoff.
_ROUNDOFF = 1e-14


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


def _Multipliers(a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv):
    """λ_a, λ_i from the slacks; λ_s, λ_o by NNLS on stationarity in a over the
    active set; and the stationarity residual."""
    e = a - v_t
    lam_a = 2 * Ma * max(0.0, e @ e - r_acc_sq)
    lam_i = 2 * Mv * np.maximum(0.0, rho - n @ a)
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
    return lam_a, lam_i, lam_s, lam_o, float(np.linalg.norm(resid))


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
    unconstrained=None,
) -> RelaxedOrcaSolution:
    """Solves one human's relaxed-ORCA QP exactly (see the module doc).

    Args:
        v_pref: preferred velocity (2,).
        v_current: current velocity v_t (2,).
        normals, offsets: agent half-planes n_iᵀa ≥ ρ_i, (A, 2) and (A,).
        max_speed, max_accel, time_step: a_max, acc_max, Δt.
        slack_weights: (M_a, M_v).
        static_normals, static_offsets: static half-planes (S, 2), (S,).
        unconstrained: f's unconstrained minimizer, if the caller has it
            (relaxed_orca_actions' compiled Newton); otherwise found here.
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
    a = v_pref.copy() if unconstrained is None else np.array(unconstrained, float)
    for _ in range(0 if unconstrained is not None else 50):
        f, g, Hm = Reduced(a, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)
        step = -np.linalg.solve(Hm, g)
        t = 1.0
        while t > 1e-8:
            trial = a + t * step
            f_trial = Reduced(trial, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[0]
            if f_trial <= f + 1e-4 * t * (g @ step) + _ROUNDOFF * (1 + abs(f)):
                break
            t *= 0.5
        a = a + t * step
        if np.linalg.norm(t * step) < 1e-13:
            break
    constrained = None
    if not feasible(a):
        # Constrained: a KKT point on the boundary (exact Newton on each
        # candidate active set), else SLSQP.
        constrained = ActiveSetMinimum(
            a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv
        )
    if constrained is not None:
        a = constrained
    elif not feasible(a):
        # SLSQP on the (smooth, convex) reduced problem.
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
            lambda x: Reduced(x, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[0],
            start,
            jac=lambda x: Reduced(x, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[1],
            constraints=cons,
            method="SLSQP",
            options={"ftol": 1e-14, "maxiter": 200},
        )
        a = res.x
        # SLSQP stops with a stationarity residual up to ~1e-5 when the
        # multipliers are large; polish on its active set, keeping the better.
        polished = PolishActiveSet(
            a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv
        )
        if polished is not None and feasible(polished):
            old = _Multipliers(
                a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv
            )
            new = _Multipliers(
                polished, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv
            )
            if new[-1] < old[-1]:
                a = polished
    e = a - v_t
    za = max(0.0, e @ e - r_acc_sq)
    zv = np.maximum(0.0, rho - n @ a)
    lam_a, lam_i, lam_s, lam_o, resid = _Multipliers(
        a, v_pref, v_t, n, rho, no, rho_o, vmax_sq, r_acc_sq, Ma, Mv
    )
    f = Reduced(a, v_pref, v_t, n, rho, r_acc_sq, Ma, Mv)[0]
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
        stationarity_residual=resid,
    )


@dataclass
class RelaxedOrcaBatch:
    """relaxed_orca_action's solutions of B independent instances, one a row
    (μ = 0 exactly, so it is left out)."""

    velocity: np.ndarray  # a (B, 2)
    slack_acceleration: np.ndarray  # ζ_a (B,)
    slack_velocity: np.ndarray  # ζ_v (B, A)
    multiplier_speed: np.ndarray  # λ_s (B,)
    multiplier_acceleration: np.ndarray  # λ_a (B,)
    multipliers_agents: np.ndarray  # λ_i (B, A)
    multipliers_static: np.ndarray  # λ_o (B, S)
    cost: np.ndarray | None  # (B,) (None: not asked for)
    stationarity_residual: np.ndarray | None  # (B,) (idem)


def relaxed_orca_actions(
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
    diagnostics=True,
) -> RelaxedOrcaBatch:
    """Solves B independent relaxed-ORCA QPs (one per human) at once.

    The same damped Newton as relaxed_orca_action on the unconstrained reduced
    problem f(a), compiled and run row by row (2×2 solves in closed form,
    Armijo backtracking; humans/kernels.py). The rare rows whose
    unconstrained minimizer leaves the speed disc or a static half-plane are
    handed to relaxed_orca_action, so they are exact too. Elsewhere
    λ_s = λ_o = 0 and the stationarity residual is ‖∇f(a)‖.

    Args:
        v_pref: preferred velocities (B, 2).
        v_current: current velocities v_t (B, 2).
        normals, offsets: agent half-planes n_iᵀa ≥ ρ_i, (B, A, 2) and (B, A).
        max_speed, max_accel, time_step: a_max (one for all, or (B,): one
            per human), acc_max, Δt.
        slack_weights: (M_a, M_v).
        static_normals, static_offsets: static half-planes (B, S, 2), (B, S).
        diagnostics: whether to compute each instance's cost and
            stationarity residual (a forward simulation needs neither).
    """
    v_pref = np.asarray(v_pref, dtype=float).reshape(-1, 2)
    v_t = np.asarray(v_current, dtype=float).reshape(-1, 2)
    B = len(v_pref)
    rho = np.asarray(offsets, dtype=float)
    A = rho.shape[-1] if rho.ndim == 2 else 0
    rho = rho.reshape(B, A)
    n = np.asarray(normals, dtype=float).reshape(B, A, 2)
    if static_offsets is None:
        no, rho_o = np.zeros((B, 0, 2)), np.zeros((B, 0))
    else:
        rho_o = np.asarray(static_offsets, dtype=float)
        S = rho_o.shape[-1] if rho_o.ndim == 2 else 0
        rho_o = rho_o.reshape(B, S)
        no = np.asarray(static_normals, dtype=float).reshape(B, S, 2)
    Ma, Mv = (float(w) for w in slack_weights)
    r_acc_sq = (time_step * max_accel) ** 2

    def slacks(a):
        e = a - v_t
        za = np.maximum(0.0, np.einsum("bk,bk->b", e, e) - r_acc_sq)
        zv = np.maximum(0.0, rho - np.einsum("bak,bk->ba", n, a))
        return e, za, zv

    def cost(a, za, zv):
        d = a - v_pref
        return (
            np.einsum("bk,bk->b", d, d) + Ma * za**2 + Mv * einsum("ba,ba->b", zv, zv)
        )

    def gradient(a, e, za, zv):
        return (
            2 * (a - v_pref)
            + (4 * Ma * za)[:, None] * e
            - 2 * Mv * einsum("ba,bak->bk", zv, n)
        )

    # Damped Newton on f (see Reduced), row by row, compiled
    # (humans/kernels.py).
    a = relaxed_orca_newton(
        np.ascontiguousarray(v_pref),
        np.ascontiguousarray(v_t),
        np.ascontiguousarray(n),
        np.ascontiguousarray(rho),
        r_acc_sq,
        Ma,
        Mv,
    )
    e, za, zv = slacks(a)
    result = RelaxedOrcaBatch(
        velocity=a,
        slack_acceleration=za,
        slack_velocity=zv,
        multiplier_speed=np.zeros(B),
        multiplier_acceleration=2 * Ma * za,
        multipliers_agents=2 * Mv * zv,
        multipliers_static=np.zeros(rho_o.shape),
        cost=cost(a, za, zv) if diagnostics else None,
        # Stationarity in a with λ_s = λ_o = 0 is ∇f(a) = 0.
        stationarity_residual=(
            np.linalg.norm(gradient(a, e, za, zv), axis=1) if diagnostics else None
        ),
    )
    # The same feasibility test as relaxed_orca_action's.
    vmax = np.broadcast_to(np.asarray(max_speed, dtype=float), (B,))
    constrained = np.einsum("bk,bk->b", a, a) > vmax**2 + 1e-12
    constrained |= np.any(np.einsum("bsk,bk->bs", no, a) < rho_o - 1e-10, axis=1)
    for b in np.flatnonzero(constrained):
        sol = relaxed_orca_action(
            v_pref[b],
            v_t[b],
            n[b],
            rho[b],
            max_speed=float(vmax[b]),
            max_accel=max_accel,
            time_step=time_step,
            slack_weights=slack_weights,
            static_normals=no[b],
            static_offsets=rho_o[b],
            unconstrained=a[b],
        )
        result.velocity[b] = sol.velocity
        result.slack_acceleration[b] = sol.slack_acceleration
        result.slack_velocity[b] = sol.slack_velocity
        result.multiplier_speed[b] = sol.multiplier_speed
        result.multiplier_acceleration[b] = sol.multiplier_acceleration
        result.multipliers_agents[b] = sol.multipliers_agents
        result.multipliers_static[b] = sol.multipliers_static
        if diagnostics:
            result.cost[b] = sol.cost
            result.stationarity_residual[b] = sol.stationarity_residual
    return result
