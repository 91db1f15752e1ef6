"""The relaxed-ORCA QP's constrained minimizer by active sets
(humans/relaxed_orca_active_set.py) against SLSQP, its former first resort
and still its fallback."""

import numpy as np

from sm2ith_drake.humans import relaxed_orca
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_action
from sm2ith_drake.humans.relaxed_orca_active_set import ActiveSetMinimum


def _Scenes(rng, count):
    """Scenes whose unconstrained minimizer leaves the speed disc or a wall's
    half-plane (fast preferred velocities, walls cutting across them, up to
    two walls and a corner)."""
    out = []
    while len(out) < count:
        A, S = rng.integers(0, 4), rng.integers(0, 3)
        speed = rng.uniform(0.8, 2.5)
        heading = rng.uniform(0, 2 * np.pi)
        v_pref = speed * np.array([np.cos(heading), np.sin(heading)])
        v_t = v_pref * rng.uniform(0.3, 1.0) + rng.normal(scale=0.2, size=2)
        ang = rng.uniform(0, 2 * np.pi, A)
        n = np.column_stack([np.cos(ang), np.sin(ang)]).reshape(-1, 2)
        rho = rng.uniform(-0.5, 0.8, A)
        # Walls facing against the preferred velocity, some of them past it.
        ang_o = heading + np.pi + rng.uniform(-1.2, 1.2, S)
        no = np.column_stack([np.cos(ang_o), np.sin(ang_o)]).reshape(-1, 2)
        rho_o = rng.uniform(-1.2, 0.2, S)
        out.append((v_pref, v_t, n, rho, no, rho_o))
    return out


def test_active_sets_find_the_slsqp_minimum_exactly():
    rng = np.random.default_rng(3)
    vmax, amax, dt, Ma, Mv = 1.5, 2.0, 0.2, 10.0, 100.0
    kinds = set()
    compared = 0
    for v_pref, v_t, n, rho, no, rho_o in _Scenes(rng, 150):
        args = dict(
            max_speed=vmax, max_accel=amax, time_step=dt, slack_weights=(Ma, Mv)
        )
        statics = dict(static_normals=no, static_offsets=rho_o)
        sol = relaxed_orca_action(v_pref, v_t, n, rho, **args, **statics)
        # The same instance with the active sets turned off: SLSQP + polish.
        original = relaxed_orca.ActiveSetMinimum
        relaxed_orca.ActiveSetMinimum = lambda *a: None
        try:
            ref = relaxed_orca_action(v_pref, v_t, n, rho, **args, **statics)
        finally:
            relaxed_orca.ActiveSetMinimum = original
        a = sol.velocity
        feasible_ref = ref.velocity @ ref.velocity <= vmax**2 + 1e-9 and np.all(
            no @ ref.velocity >= rho_o - 1e-8
        )
        if not feasible_ref:
            continue  # walls and disc without a common point: nothing to compare
        compared += 1
        # Never worse than SLSQP (up to its tolerance), at the same point.
        assert sol.cost <= ref.cost + 1e-9 * max(1.0, ref.cost)
        np.testing.assert_allclose(a, ref.velocity, atol=1e-6)
        assert sol.stationarity_residual < 1e-8
        assert a @ a <= vmax**2 + 1e-12 and np.all(no @ a >= rho_o - 1e-10)
        on_disc = abs(a @ a - vmax**2) < 1e-9
        on_walls = int(np.sum(np.abs(no @ a - rho_o) < 1e-9))
        kinds.add((on_disc, on_walls))
    assert compared >= 100
    # Every kind of boundary piece: the disc, a wall, a wall and the disc,
    # a corner of two walls.
    assert {(True, 0), (False, 1), (True, 1), (False, 2)} <= kinds


def test_active_set_minimum_is_none_when_nothing_is_feasible():
    """Two walls that exclude each other: no KKT point, so the caller falls
    back to SLSQP rather than returning an infeasible point."""
    no = np.array([[1.0, 0.0], [-1.0, 0.0]])
    rho_o = np.array([0.5, 0.5])  # a_x ≥ 0.5 and a_x ≤ −0.5
    v_pref, v_t = np.array([1.0, 0.0]), np.zeros(2)
    n, rho = np.zeros((0, 2)), np.zeros(0)
    a = v_pref.copy()
    args = (v_pref, v_t, n, rho, no, rho_o, 1.5**2, 0.16, 10.0, 100.0)
    assert ActiveSetMinimum(a, *args) is None
