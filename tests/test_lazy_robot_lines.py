"""Lazy robot lines (controller.lazy_line_margin): PIQP's stage QPs leave out
the primal rows of a predicted person's lines of the robot that are
inactive by the margin, check them at the solution, and solve those lines'
complementarity rows without their robot entries, so that a person's block
does not tie into the robot's configuration."""

import numpy as np
import pytest
import scipy.sparse as sp
from test_inside_barrier import _Controller
from test_lazy_rows import TIGHT, PlanOneStep, TightPiqp
from test_piqp_workspace import EQUALITIES, ROWS, _Clarabel, _RandomQp

from sm2ith_drake.scenario import ControllerConfig

# One person beside the robot, two metres away.
PEOPLE = [[0.9, 0.7], [2.5, 1.5], [3.0, -2.0]]
MARGIN = 0.25


def _Group(c):
    groups = (g for g, _, _ in c.program.extra_constraints)
    return next(g for g in groups if g.name == "orca_kkt_inequalities")


def test_far_robot_lines_are_the_inactive_lines_of_the_robot():
    c, point, _, _ = _Controller("decay", PEOPLE)
    group = _Group(c)
    assert group.FarRows(point, 0.0) is None
    assert group.FarEntries(point, 0.0) is None
    K = c.predictor.num_neighbors
    R = group.blocks.num_multipliers
    lines = np.arange(2 + K, 4 + K)
    c_lines = group.blocks.Evaluate(point).c[..., lines]  # (N, H, 2)
    far = c_lines < -MARGIN
    assert far.any() and not far.all()

    rows = group.FarRows(point, MARGIN).reshape(far.shape[:2] + (2 * R,))
    np.testing.assert_array_equal(rows[..., lines], far)
    rows[..., lines] = False
    assert not rows.any()  # no other line, no complementarity row

    entries = group.FarEntries(point, MARGIN)
    assert entries.shape == group.rows.shape
    block, local = np.divmod(group.rows, 2 * R)
    robot = group.cols < c.program.layout.robot_variables
    line = local - R - lines[0]
    in_far_line = (line >= 0) & (line < 2)
    in_far_line[in_far_line] = far.reshape(-1, 2)[block[in_far_line], line[in_far_line]]
    # Exactly the robot's entries of the far lines' complementarity rows.
    np.testing.assert_array_equal(entries, in_far_line & robot)
    assert entries.any()


@pytest.mark.parametrize("seed", range(3))
def test_far_entries_are_solved_as_zeros(seed):
    """The workspace solves the QP whose far entries are zero."""
    rng = np.random.default_rng(seed)
    ws, args, P, _ = _RandomQp(rng, TIGHT)
    p_values, q, a_values, x_lower, x_upper, _, _ = args
    far = rng.random(a_values.size) < 0.3
    arows, acols = ws._a_rows, ws._a_cols
    A = sp.coo_matrix(
        (np.where(far, 0.0, a_values), (arows, acols)), shape=(ROWS, P.shape[0])
    ).toarray()
    x0 = 0.5 * (x_lower + x_upper)
    lower, upper = A @ x0 - rng.random(ROWS), A @ x0 + rng.random(ROWS)
    lower[EQUALITIES] = upper[EQUALITIES] = (A @ x0)[EQUALITIES]
    qp = (p_values, q, a_values, x_lower, x_upper, lower, upper)
    x, status, _ = ws.Solve(*qp, far_entries=far)
    assert status == "solved"
    expected = _Clarabel(P, q, A, x_lower, x_upper, lower, upper)
    np.testing.assert_allclose(x, expected, atol=1e-4)
    x_whole, _, _ = ws.Solve(*qp)
    assert np.max(np.abs(x_whole - expected)) > 1e-2


@pytest.mark.parametrize("seed", range(2))
def test_far_rows_are_checked_and_put_back_with_the_lazy_rows(seed):
    """Far rows are left out and checked as lazy rows are: every inequality
    row split between the two masks, the solution is still the whole QP's,
    and every row that binds there was put back, in the mask it came in."""
    ws, args, P, A = _RandomQp(np.random.default_rng(seed), TIGHT)
    p_values, q, a_values, x_lower, x_upper, lower, upper = args
    expected = _Clarabel(P, q, A, x_lower, x_upper, lower, upper)
    inequality = np.ones(ROWS, dtype=bool)
    inequality[EQUALITIES] = False
    half = np.arange(ROWS) % 2 == 0
    lazy, far = inequality & half, inequality & ~half
    x, status, _ = ws.Solve(*args, lazy_rows=lazy, far_rows=far)
    assert status == "solved"
    np.testing.assert_allclose(x, expected, atol=1e-6)
    value = A @ expected
    binding = inequality & ((value < lower + 1e-4) | (value > upper - 1e-4))
    assert (binding & half).any() and (binding & ~half).any()
    assert not ((lazy | far) & binding).any()
    assert not (lazy & ~half).any() and not (far & half).any()


def _Plan(qp_solver, margin, tight):
    config = ControllerConfig(horizon=3, qp_solver=qp_solver, lazy_line_margin=margin)
    if tight:
        config.solver_options = TightPiqp()
    far = (lambda c, point: _Group(c).FarRows(point, margin)) if margin else None
    return PlanOneStep(config, PEOPLE, far)


def test_the_controller_plans_the_same_with_lazy_robot_lines():
    """One step of SM²ITH's hierarchy with PIQP (tight tolerances, as in
    test_lazy_rows): the same plan with the far lines left out."""
    whole, lazy = _Plan("piqp", 0.0, True), _Plan("piqp", MARGIN, True)
    np.testing.assert_allclose(lazy.q, whole.q, atol=1e-6)
    np.testing.assert_allclose(lazy.u, whole.u, atol=1e-5)


def test_hpipm_keeps_every_row_and_entry():
    """HPIPM's QPs (up to ~3 people) are solved whole: the same plan, to
    the bit, with the option on."""
    whole, lazy = _Plan("hpipm", 0.0, False), _Plan("hpipm", MARGIN, False)
    np.testing.assert_array_equal(lazy.q, whole.q)
    np.testing.assert_array_equal(lazy.u, whole.u)
