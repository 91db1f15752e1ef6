"""PiqpWorkspace: a QP with a fixed pattern whose values may be exactly zero
at a point. A fresh PIQP set-up gets the matrices without their stored zeros;
the pattern itself must survive that, so the next QP on it (with other zeros)
is solved as given. Checked against Drake's Clarabel on the same QPs."""

import numpy as np
import pytest
import scipy.sparse as sp
from pydrake.solvers import ClarabelSolver, MathematicalProgram

from sm2ith_drake.control.hpipm_workspace import CheckHpipmSettings
from sm2ith_drake.control.piqp_workspace import (
    INACCURATE_PRIMAL,
    PIQP_DEFAULT_SETTINGS,
    CheckPiqpSettings,
    NearlySolved,
    PiqpBuild,
    PiqpWorkspace,
    _WithoutZeros,
)
from sm2ith_drake.errors import UserError

N, ROWS = 12, 10
EQUALITIES = np.array([0, 3])


def _Pattern(rng):
    """A random constraint pattern (each row 2–6 columns) and a P pattern
    (the diagonal and a few symmetric pairs)."""
    arows, acols = [], []
    for r in range(ROWS):
        cols = rng.choice(N, size=rng.integers(2, 7), replace=False)
        arows += [r] * cols.size
        acols += list(cols)
    pairs = rng.choice(N, size=(4, 2))
    prow = np.concatenate([np.arange(N), pairs[:, 0], pairs[:, 1]])
    pcol = np.concatenate([np.arange(N), pairs[:, 1], pairs[:, 0]])
    return (np.array(prow), np.array(pcol)), (np.array(arows), np.array(acols))


def _Workspace(p_pattern, a_pattern, settings):
    """A PiqpWorkspace on the patterns with PIQP's default settings and
    ``settings`` over them."""
    return PiqpWorkspace(
        num_variables=N,
        p_pattern=p_pattern,
        a_pattern=a_pattern,
        equality_rows=EQUALITIES,
        settings=dict(PIQP_DEFAULT_SETTINGS, **settings),
    )


def _Clarabel(P, q, A, x_lower, x_upper, lower, upper):
    prog = MathematicalProgram()
    x = prog.NewContinuousVariables(N)
    prog.AddQuadraticCost(P, q, x, is_convex=True)
    prog.AddBoundingBoxConstraint(x_lower, x_upper, x)
    prog.AddLinearConstraint(A, lower, upper, x)
    result = ClarabelSolver().Solve(prog)
    assert result.is_success()
    return result.GetSolution(x)


def _Builds():
    """The PIQP builds this machine can run (generic always)."""
    builds = ["generic", "auto"]
    for name in ("avx2", "avx512"):
        try:
            PiqpBuild(name)
            builds.append(name)
        except UserError:
            pass
    return builds


@pytest.mark.parametrize("build", ["generic", "auto", "avx2", "avx512"])
@pytest.mark.parametrize("seed", range(5))
def test_stored_zeros_do_not_change_the_solution_nor_the_pattern(seed, build):
    """Also: every PIQP build (PiqpWorkspace's instruction_set) solves the
    same QPs as Clarabel."""
    if build not in _Builds():
        pytest.skip(f"PIQP's {build} build does not run on this machine")
    rng = np.random.default_rng(seed)
    p_pattern, a_pattern = _Pattern(rng)
    ws = _Workspace(
        p_pattern,
        a_pattern,
        dict(
            instruction_set=build,
            eps_abs=1e-9,
            eps_rel=1e-10,
            eps_duality_gap_abs=1e-10,
            eps_duality_gap_rel=1e-10,
        ),
    )
    prow, pcol = ws.p_pattern
    indices_before = (prow.copy(), pcol.copy())
    arows, acols = a_pattern
    for _ in range(3):
        # Values with a third of the entries exactly zero, different each QP.
        a_values = rng.normal(size=arows.size) * (rng.random(arows.size) > 0.33)
        off = rng.normal(scale=0.3, size=prow.size) * (rng.random(prow.size) > 0.33)
        p_values = np.where(prow == pcol, 2.0 + rng.random(prow.size), off)
        q = rng.normal(size=N)
        A = sp.coo_matrix((a_values, (arows, acols)), shape=(ROWS, N)).toarray()
        x0 = rng.normal(size=N)  # a feasible point for the rows
        lower, upper = A @ x0 - rng.random(ROWS), A @ x0 + rng.random(ROWS)
        lower[EQUALITIES] = upper[EQUALITIES] = (A @ x0)[EQUALITIES]
        x_lower, x_upper = x0 - 1.0, x0 + 1.0
        x, status, _ = ws.Solve(p_values, q, a_values, x_lower, x_upper, lower, upper)
        assert status == "solved"
        upper_p = sp.coo_matrix((p_values, (prow, pcol)), shape=(N, N)).toarray()
        P = upper_p + np.triu(upper_p, 1).T
        expected = _Clarabel(P, q, A, x_lower, x_upper, lower, upper)
        np.testing.assert_allclose(x, expected, atol=1e-5)
        # The workspace's pattern arrays are untouched by the pruning.
        np.testing.assert_array_equal(ws.p_pattern[0], indices_before[0])
        np.testing.assert_array_equal(ws.p_pattern[1], indices_before[1])


def test_without_zeros_keeps_the_matrix_and_leaves_the_input_alone():
    rng = np.random.default_rng(0)
    for trial in range(100):
        M = sp.random(
            9, 7, density=rng.uniform(0, 0.6), format="csc", random_state=trial
        )
        M.data[rng.random(M.nnz) < 0.4] = 0.0
        indices, indptr = M.indices.copy(), M.indptr.copy()
        W = _WithoutZeros(M)
        np.testing.assert_array_equal(W.toarray(), M.toarray())
        assert np.all(W.data != 0) and W.has_sorted_indices
        np.testing.assert_array_equal(M.indices, indices)
        np.testing.assert_array_equal(M.indptr, indptr)


def test_the_generic_build_is_the_default_and_a_bad_one_is_named():
    assert PIQP_DEFAULT_SETTINGS["instruction_set"] == "generic"
    assert PiqpBuild("generic").__name__ == "piqp.piqp_python"
    ws = PiqpWorkspace(
        num_variables=2,
        p_pattern=(np.arange(2), np.arange(2)),
        a_pattern=(np.array([0, 0]), np.array([0, 1])),
        equality_rows=np.zeros(0, dtype=int),
        settings=dict(PIQP_DEFAULT_SETTINGS),
    )
    assert ws._piqp is PiqpBuild("generic")
    assert "instruction_set" not in ws.settings  # not handed to PIQP
    with pytest.raises(UserError, match="instruction_set 'sse9'.*generic"):
        PiqpBuild("sse9")


def _RandomQp(rng, settings):
    """A workspace on a random pattern and one feasible QP on it: (ws, the
    Solve arguments, the dense P and A)."""
    p_pattern, a_pattern = _Pattern(rng)
    ws = _Workspace(p_pattern, a_pattern, settings)
    prow, pcol = ws.p_pattern
    arows, acols = a_pattern
    a_values = rng.normal(size=arows.size)
    p_values = np.where(prow == pcol, 2.0 + rng.random(prow.size), 0.1)
    q = rng.normal(size=N) * 100.0
    A = sp.coo_matrix((a_values, (arows, acols)), shape=(ROWS, N)).toarray()
    x0 = rng.normal(size=N)
    lower, upper = A @ x0 - rng.random(ROWS), A @ x0 + rng.random(ROWS)
    lower[EQUALITIES] = upper[EQUALITIES] = (A @ x0)[EQUALITIES]
    args = (p_values, q, a_values, x0 - 1.0, x0 + 1.0, lower, upper)
    upper_p = sp.coo_matrix((p_values, (prow, pcol)), shape=(N, N)).toarray()
    return ws, args, upper_p + np.triu(upper_p, 1).T, A


# (Seed 2's QP meets even those tolerances: PIQP reports it solved.)
@pytest.mark.parametrize("seed", [0, 1, 3, 4, 5])
def test_an_iteration_limit_on_a_converged_iterate_counts_as_solved(seed):
    """Tolerances PIQP cannot reach make it stop at max_iter on an iterate
    that is as good as solved: that is "solved_inaccurate" (a success for
    the stage solvers) and matches Clarabel. Stopped after 2 iterations,
    far from the optimum, it stays "max_iter_reached"."""
    unreachable = dict(
        eps_abs=1e-15,
        eps_rel=1e-16,
        eps_duality_gap_abs=1e-16,
        eps_duality_gap_rel=1e-16,
    )
    ws, args, P, A = _RandomQp(
        np.random.default_rng(seed), dict(unreachable, max_iter=80)
    )
    x, status, iterations = ws.Solve(*args)
    assert (status, iterations) == ("solved_inaccurate", 80)
    p_values, q, _, x_lower, x_upper, lower, upper = args
    expected = _Clarabel(P, q, A, x_lower, x_upper, lower, upper)
    np.testing.assert_allclose(x, expected, atol=1e-5)

    ws, args, _, _ = _RandomQp(np.random.default_rng(seed), dict(max_iter=2))
    _, status, iterations = ws.Solve(*args)
    assert (status, iterations) == ("max_iter_reached", 2)


def test_nearly_solved_checks_every_constraint_on_the_problems_own_data():
    class Info:
        duality_gap_rel = 1e-6
        dual_res_rel = 1e-8

    A, b = sp.csc_matrix([[1.0, 1.0]]), np.array([1.0])
    G = sp.csc_matrix([[1.0, -1.0]])
    h_l, h_u = np.array([-np.inf]), np.array([0.0])
    x_lower, x_upper = np.array([0.0, 0.0]), np.array([1.0, np.inf])
    P = sp.identity(2, format="csc")
    ok = np.array([0.5, 0.5])

    def Check(x, info=Info):
        return NearlySolved(info, np.asarray(x), P, A, b, G, h_l, h_u, x_lower, x_upper)

    assert Check(ok)
    off = 10 * INACCURATE_PRIMAL
    assert not Check(ok + [off, 0.0])  # the equality
    assert not Check([0.5 + off, 0.5 - off])  # the inequality
    assert not Check([-off, 1.0 + off])  # a bound
    assert not Check([np.nan, 0.5])

    class FarGap(Info):
        duality_gap_rel = 1e-2

    class FarDual(Info):
        dual_res_rel = 1e-2

    assert not Check(ok, FarGap) and not Check(ok, FarDual)


def test_solver_settings_read_as_text_become_numbers():
    """YAML 1.1 reads 1e-4 (no decimal point) as text: the settings check
    turns it into the number PIQP and HPIPM take, by each setting's type."""
    checked = CheckPiqpSettings({"eps_abs": "1e-4", "max_iter": 40, "verbose": False})
    assert checked == {"eps_abs": 1e-4, "max_iter": 40, "verbose": False}
    assert isinstance(checked["eps_abs"], float)
    hpipm = CheckHpipmSettings(
        {"mu0": 10000, "iter_max": "30", "warm_start": True, "auto_max_work": "6e6"}
    )
    assert hpipm == {
        "mu0": 10000.0,
        "iter_max": 30,
        "warm_start": 1,
        "auto_max_work": 6e6,
    }
    assert isinstance(hpipm["mu0"], float) and isinstance(hpipm["iter_max"], int)
    with pytest.raises(UserError, match="not a finite number"):
        CheckHpipmSettings({"tol_stat": float("nan")})
