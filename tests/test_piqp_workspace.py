"""PiqpWorkspace: a QP with a fixed pattern whose values may be exactly zero
at a point. A fresh PIQP set-up gets the matrices without their stored zeros;
the pattern itself must survive that, so the next QP on it (with other zeros)
is solved as given. Checked against Drake's Clarabel on the same QPs."""

import numpy as np
import pytest
import scipy.sparse as sp
from pydrake.solvers import ClarabelSolver, MathematicalProgram

from sm2ith_drake.control.piqp_workspace import (
    PIQP_DEFAULT_SETTINGS,
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
    ws = PiqpWorkspace(
        num_variables=N,
        p_pattern=p_pattern,
        a_pattern=a_pattern,
        equality_rows=EQUALITIES,
        settings=dict(
            PIQP_DEFAULT_SETTINGS,
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
