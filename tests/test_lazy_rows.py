"""Lazy rows (controller.lazy_barrier_distance): PIQP's stage QPs leave out
the DT-CBF rows of people far from a robot body, check them at the solution
and put back those it violates, so the plan is the whole QP's."""

import numpy as np
import pytest
from pydrake.solvers import SolverOptions
from test_inside_barrier import POSITIONS, _Controller
from test_piqp_workspace import EQUALITIES, ROWS, _Clarabel, _RandomQp

from sm2ith_drake.scenario import ControllerConfig

TIGHT = dict(
    eps_abs=1e-10, eps_rel=1e-11, eps_duality_gap_abs=1e-10, eps_duality_gap_rel=1e-10
)


def test_far_rows_are_the_predicted_peoples_rows_clear_at_both_knots():
    c, point, _, _ = _Controller("decay", POSITIONS)
    cbf = c.program.cbf
    h_hum = cbf.Barriers(point)[0]  # (N + 1, H, C)
    N, H, C = h_hum.shape[0] - 1, h_hum.shape[1], h_hum.shape[2]
    assert cbf.FarRows(point, 0.0) is None
    for distance in (0.25, 1.0):
        far = cbf.FarRows(point, distance)
        assert far.shape == (cbf.num_rows,)
        main = far[: N * cbf.rows_per_step].reshape(N, cbf.rows_per_step)
        expected = (h_hum[:-1] > distance) & (h_hum[1:] > distance)
        np.testing.assert_array_equal(main[:, : H * C], expected.reshape(N, -1))
        # Walls and guards are never left out.
        assert not main[:, H * C :].any()
        assert not far[N * cbf.rows_per_step :].any()
    far = cbf.FarRows(point, 0.25).reshape(-1)[: N * cbf.rows_per_step]
    rows = far.reshape(N, -1)[:, : H * C].reshape(N, H, C)
    # The person 2.9 m away is far at every knot, the one inside the
    # margin at none of the first.
    assert rows[:, 0].all() and not rows[0, 1].any()


@pytest.mark.parametrize("seed", range(4))
def test_lazy_rows_give_the_whole_qps_solution(seed):
    """Inactive rows left out: the same solution, the mask untouched. Every
    inequality row marked lazy: the violated ones (and those near their
    bounds) are put back, and the solution is still the whole QP's."""
    ws, args, P, A = _RandomQp(np.random.default_rng(seed), TIGHT)
    p_values, q, a_values, x_lower, x_upper, lower, upper = args
    expected = _Clarabel(P, q, A, x_lower, x_upper, lower, upper)
    x_full, status, _ = ws.Solve(*args)
    assert status == "solved"
    np.testing.assert_allclose(x_full, expected, atol=1e-6)
    value = A @ x_full
    inequality = np.ones(ROWS, dtype=bool)
    inequality[EQUALITIES] = False
    clear = inequality & (value > lower + 0.1) & (value < upper - 0.1)
    lazy = clear.copy()
    x, status, _ = ws.Solve(*args, lazy_rows=lazy)
    assert status == "solved"
    np.testing.assert_allclose(x, expected, atol=1e-6)
    np.testing.assert_array_equal(lazy, clear)

    lazy = inequality.copy()
    x, status, _ = ws.Solve(*args, lazy_rows=lazy)
    assert status == "solved"
    np.testing.assert_allclose(x, expected, atol=1e-6)
    binding = inequality & ((value < lower + 1e-4) | (value > upper - 1e-4))
    assert binding.any()
    # Every row that binds at the optimum was put back.
    assert not (lazy & binding).any()


# One person far from the robot, one near it but clear of its margin.
CLEAR = [[2.5, 1.5], [0.9, 0.7]]


def TightPiqp() -> SolverOptions:
    """PIQP at the TIGHT tolerances."""
    options = SolverOptions()
    options.options = {"PIQP": dict(TIGHT)}
    return options


def PlanOneStep(config, people, far=None):
    """One step of SM²ITH's hierarchy with ``config`` (_Controller's
    Stretch 3 among ``people``), from the warm start itself (_Controller's
    perturbed one is infeasible). ``far(c, point)``, if given, must leave
    some rows out at the warm start, not all."""
    c, _, _, targets = _Controller("decay", people, config=config)
    q0 = c.robot.default_q.copy()
    nu0 = np.zeros(c.robot.num_velocities)
    nu0[:2] = [0.2, 0.4]
    z = c.WarmStart(c.InitialState(), q0, nu0)
    if far is not None:
        rows = far(c, c.program.MakePoint(z, targets))
        assert rows.any() and not rows.all()
    solution = c.solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z)
    assert solution.success, solution.status
    return solution


def test_the_controller_plans_the_same_with_lazy_rows():
    """One step of SM²ITH's hierarchy with PIQP (tight tolerances: the stage
    QPs are degenerate, and at PIQP's shipped ones two solves of the same QP
    differ by ~1e-3), every row against lazy rows at 0.25 m: the same plan,
    with rows left out."""
    plans = []
    for distance in (0.0, 0.25):
        config = ControllerConfig(
            horizon=3,
            qp_solver="piqp",
            lazy_barrier_distance=distance,
            solver_options=TightPiqp(),
        )
        far = None
        if distance:

            def far(c, point, distance=distance):
                return c.program.cbf.FarRows(point, distance)

        plans.append(PlanOneStep(config, CLEAR, far))
    np.testing.assert_allclose(plans[1].q, plans[0].q, atol=1e-6)
    np.testing.assert_allclose(plans[1].u, plans[0].u, atol=1e-5)


def test_a_qp_not_solved_without_the_lazy_rows_is_solved_with_every_row():
    """PIQP stopped after 2 iterations fails the QP without its lazy rows;
    the workspace then solves the whole QP (here: fails it too, with the
    iterations of both solves counted)."""
    ws, args, _, _ = _RandomQp(np.random.default_rng(0), dict(max_iter=2))
    lazy = np.ones(ROWS, dtype=bool)
    calls = []
    solve = ws._Solve

    def Spy(*a):
        calls.append(a[1] if len(a) > 1 else None)
        return solve(*a)

    ws._Solve = Spy
    _, status, iterations = ws.Solve(*args, lazy_rows=lazy)
    assert status == "max_iter_reached" and iterations == 4
    assert calls[0] is not None and calls[1] is None


def test_an_iteration_cap_holds_over_every_round_and_leaves_the_settings():
    """``max_iterations`` caps PIQP's iterations over the lazy rounds and
    the every-row solve together; the next solve without a cap solves the
    QP as before (PIQP's own max_iter restored)."""
    ws, args, _, _ = _RandomQp(np.random.default_rng(0), {})
    x_full, status, full = ws.Solve(*args)
    assert status == "solved" and full > 3
    x_again, status, iterations = ws.Solve(
        *args, lazy_rows=np.ones(ROWS, dtype=bool), max_iterations=3
    )
    assert status == "max_iter_reached" and iterations == 3
    x_after, status, after = ws.Solve(*args)
    assert status == "solved" and after == full
    np.testing.assert_array_equal(x_after, x_full)
    # A cap above what the QP needs changes nothing.
    x_capped, status, capped = ws.Solve(*args, max_iterations=full + 1)
    assert status == "solved" and capped == full
    np.testing.assert_array_equal(x_capped, x_full)
