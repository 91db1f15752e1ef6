"""HPIPM as the stage-QP solver (controller.qp_solver: hpipm): the OCP form
of a stage QP against PIQP on the same QPs, reproducibility, structure
errors, and the message when the optional extra is missing."""

import importlib.util

import numpy as np
import pytest
import scipy.sparse as sp

from sm2ith_drake.control import hpipm_library
from sm2ith_drake.control.batched_solve import solve_batched
from sm2ith_drake.control.groups import INPUT, OTHER, STATE, VariableLayout
from sm2ith_drake.control.hpipm_workspace import HpipmWorkspace
from sm2ith_drake.control.piqp_workspace import PIQP_DEFAULT_SETTINGS, PiqpWorkspace
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario

needs_hpipm = pytest.mark.skipif(
    not hpipm_library.Available(),
    reason="HPIPM is the optional extra sm2ith_drake[hpipm] (Python >= 3.12)",
)


def _Crossing(name: str):
    return LoadScenario(
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        scenario_name=name,
        scenario_text="{controller: {qp_solver: hpipm}}",
    )


def _Piqp(ws: HpipmWorkspace, tolerance: float | None = 1e-9):
    """A PIQP workspace on the same pattern, solving to ``tolerance`` (the
    reference: tighter than the controller's; None: the controller's own
    settings), and P's values mapped to it."""
    settings = dict(PIQP_DEFAULT_SETTINGS)
    if tolerance is not None:
        settings.update(
            eps_abs=tolerance,
            eps_rel=tolerance,
            eps_duality_gap_abs=tolerance,
            eps_duality_gap_rel=tolerance,
        )
    piqp = PiqpWorkspace(
        num_variables=ws.n,
        p_pattern=ws.p_pattern,
        a_pattern=(ws.a_rows, ws.a_cols),
        equality_rows=np.nonzero(ws.equality)[0],
        settings=settings,
    )
    rows, cols = ws.p_pattern
    pr, pc = piqp.p_pattern

    def Values(p_values):
        P = sp.csr_matrix((p_values, (rows, cols)), shape=(ws.n, ws.n))
        return np.asarray(P[pr, pc]).ravel()

    return piqp, Values


def _Objective(ws, p_values, q, z):
    rows, cols = ws.p_pattern
    P = sp.csr_matrix((p_values, (rows, cols)), shape=(ws.n, ws.n))
    return (
        0.5 * z @ (P @ z) + 0.5 * z @ (P.T @ z) - 0.5 * z @ (P.diagonal() * z) + (q @ z)
    )


def _Violation(ws, a_values, z, x_lower, x_upper, lower, upper):
    A = sp.csr_matrix((a_values, (ws.a_rows, ws.a_cols)), shape=(ws.num_rows, ws.n))
    g = A @ z
    return max(
        np.max(lower - g, initial=0),
        np.max(g - upper, initial=0),
        np.max(x_lower - z, initial=0),
        np.max(z - x_upper, initial=0),
    )


@needs_hpipm
def test_hpipm_solves_the_stage_qps_as_piqp_does(monkeypatch):
    """Every stage QP of a 3-person crossing (Stretch 3, SM²ITH), solved by
    HPIPM in its OCP form and by PIQP as a sparse QP to 1e-9: the same
    optimal value, HPIPM's solution feasible; the plans agree to what the
    QPs' degeneracy allows. (PIQP at the controller's own tolerances lands
    up to ~2e-5 of the value further off than HPIPM.)"""
    scenario = _Crossing("crossing_stretch3_3h")
    compared = []
    solve = HpipmWorkspace.Solve

    def Comparing(self, p_values, q, a_values, x_lower, x_upper, lower, upper, **kw):
        args = (a_values, x_lower, x_upper, lower, upper)
        z, status, iterations = solve(self, p_values, q, *args, **kw)
        piqp, Values = _Piqp(self)
        zp, status_p, _ = piqp.Solve(Values(p_values), q, *args)
        compared.append(
            (
                status,
                status_p,
                _Objective(self, p_values, q, z),
                _Objective(self, p_values, q, zp),
                _Violation(self, a_values, z, x_lower, x_upper, lower, upper),
                np.abs(z - zp).max(),
            )
        )
        return z, status, iterations

    monkeypatch.setattr(HpipmWorkspace, "Solve", Comparing)
    result = RunSimulation(scenario, duration=1.0)
    assert all(r.mode == "solved" for r in result.log.records)
    assert len(compared) >= 10
    gaps = []
    for status, status_p, f, fp, violation, gap in compared:
        assert status == status_p == "solved"
        assert abs(f - fp) <= 1e-5 * (1 + abs(fp)), (f, fp)
        # Equality rows are widened by 1e-7 for HPIPM (hpipm_workspace).
        assert violation <= 2e-7
        gaps.append(gap)
    assert np.median(gaps) < 1e-3 and max(gaps) < 5e-2


def _RecordSolves(monkeypatch):
    """Records every HpipmWorkspace solve's workspace and arguments;
    returns (calls, the unrecorded Solve)."""
    calls = []
    solve = HpipmWorkspace.Solve

    def Recording(self, *args, **kw):
        calls.append((self, [np.array(a, copy=True) for a in args]))
        return solve(self, *args, **kw)

    monkeypatch.setattr(HpipmWorkspace, "Solve", Recording)
    return calls, solve


def _RecordedCrossing(monkeypatch):
    """The solves of a short crossing: the unrecorded Solve, every recorded
    call, the first call's workspace and arguments, and the arguments of
    that workspace's later calls."""
    calls, solve = _RecordSolves(monkeypatch)
    RunSimulation(_Crossing("crossing_ridgeback_ur10_2h"), duration=0.6)
    ws, first = calls[0]
    again = [args for w, args in calls[1:] if w is ws]
    assert again
    return solve, calls, ws, first, again


@needs_hpipm
def test_hpipm_results_do_not_depend_on_earlier_solves(monkeypatch):
    """One workspace per pattern is reused: solving A, then B, then A again
    gives A's solution to the last bit (so a cloned Context reproduces a
    run)."""
    solve, calls, ws, first, again = _RecordedCrossing(monkeypatch)
    z1, _, _ = solve(ws, *first)
    solve(ws, *again[-1])
    z2, _, _ = solve(ws, *first)
    np.testing.assert_array_equal(z1, z2)
    # Each solve gathers only the positions it writes; the staged rest
    # (zeros, the padding's 0 and 1) is what a full gather would give.
    staged = [s for w, _ in calls for s in w._structures.values() if hasattr(s, "flat")]
    assert staged
    for structure in staged:
        full = np.take(structure.flat, structure.gather_index)
        np.testing.assert_array_equal(structure.staging[: full.size], full)


def _TinyMpc(span_two_knots: bool, fixed_row=None, **workspace):
    """x_{k+1} = x_k + u_k (N = 2, x_0 = 1), ½Σx² + ½Σu², a slack-relaxed
    lower bound on x_2, if asked a row tying x_0 and x_2, and with
    ``fixed_row`` = (lower, upper) a row lower ≤ x_0 + ν_0 ≤ upper of fixed
    variables only."""
    layout = VariableLayout(num_positions=1, num_velocities=1, horizon=2)
    q, nu, u = layout.q.ravel(), layout.nu.ravel(), layout.u.ravel()
    s = layout.AddVariables("slack", (1,))
    role, knot = layout.Roles()
    n = layout.num_variables
    rows, cols, vals, lo, hi = [], [], [], [], []

    def Row(entries, lower, upper):
        r = len(lo)
        for c, v in entries:
            rows.append(r)
            cols.append(c)
            vals.append(v)
        lo.append(lower)
        hi.append(upper)

    for k in range(2):
        Row([(q[k + 1], 1.0), (q[k], -1.0), (u[k], -1.0)], 0.0, 0.0)
        Row([(nu[k + 1], 1.0), (nu[k], -1.0)], 0.0, 0.0)
    Row([(q[2], 1.0), (s[0], 1.0)], 0.8, np.inf)
    if span_two_knots:
        Row([(q[2], 1.0), (q[0], -1.0)], -1.0, 1.0)
    if fixed_row is not None:
        Row([(q[0], 1.0), (nu[0], 1.0)], *fixed_row)
    ws = HpipmWorkspace(
        num_variables=n,
        p_pattern=(np.arange(n), np.arange(n)),
        a_pattern=(np.array(rows), np.array(cols)),
        equality_rows=np.arange(4),
        roles=(role, knot),
        **{"settings": {}, **workspace},
    )
    p_values = np.ones(n)
    p_values[s] = 10.0
    qvec = np.zeros(n)
    qvec[s] = 5.0
    x_lower, x_upper = np.full(n, -np.inf), np.full(n, np.inf)
    x_lower[[q[0], nu[0]]] = x_upper[[q[0], nu[0]]] = 1.0
    x_lower[s] = 0.0
    args = (np.array(vals), x_lower, x_upper, np.array(lo), np.array(hi))
    return ws, p_values, qvec, args, role, layout


@needs_hpipm
def test_hpipm_matches_piqp_on_a_small_mpc():
    ws, p_values, q, args, role, layout = _TinyMpc(span_two_knots=False)
    assert role[layout.q[1, 0]] == STATE and role[layout.u[1, 0]] == INPUT
    assert role[-1] == OTHER
    z, status, _ = ws.Solve(p_values, q, *args)
    piqp, Values = _Piqp(ws)
    zp, status_p, _ = piqp.Solve(Values(p_values), q, *args)
    assert status == status_p == "solved"
    np.testing.assert_allclose(z, zp, atol=1e-6)
    # The bound on x_2 is active: the slack takes what the cost prefers.
    assert z[layout.q[2, 0]] + z[-1] == pytest.approx(0.8, abs=1e-6)


@needs_hpipm
def test_a_qp_without_the_time_structure_is_an_error_not_a_crash():
    ws, p_values, q, args, _, _ = _TinyMpc(span_two_knots=True)
    z, status, iterations = ws.Solve(p_values, q, *args)
    assert z is None and iterations == 0
    assert status.startswith("qp error:") and "two knots" in status


@needs_hpipm
@pytest.mark.parametrize("span_two_knots", [False, True])
def test_auto_hands_wide_or_unstructured_qps_to_piqp(span_two_knots):
    """qp_solver auto: a pattern over the work limit, or without the time
    structure, is solved by PIQP (the same solution as PIQP's own)."""
    auto = dict(piqp_settings=dict(PIQP_DEFAULT_SETTINGS))
    for settings in ({}, {"auto_max_work": 0.0}):
        ws, p_values, q, args, _, _ = _TinyMpc(
            span_two_knots, settings=settings, **auto
        )
        z, status, iterations = ws.Solve(p_values, q, *args)
        piqp, Values = _Piqp(ws, tolerance=None)
        zp, _, iterations_p = piqp.Solve(Values(p_values), q, *args)
        assert status == "solved"
        delegated = span_two_knots or settings
        assert (ws._piqp is not None) == bool(delegated)
        if delegated:
            np.testing.assert_array_equal(z, zp)
        else:
            np.testing.assert_allclose(z, zp, atol=1e-6)


@needs_hpipm
def test_auto_hands_a_qp_hpipm_did_not_solve_to_piqp():
    """With one iteration allowed HPIPM's fast mode cannot solve the QP:
    hpipm re-solves it in the balanced mode, auto with PIQP."""
    piqp_settings = dict(PIQP_DEFAULT_SETTINGS)
    for auto in (False, True):
        extra = dict(piqp_settings=piqp_settings) if auto else {}
        ws, p_values, q, args, _, _ = _TinyMpc(False, settings={"iter_max": 1}, **extra)
        z, status, _ = ws.Solve(p_values, q, *args)
        assert status == "solved"
        assert (ws._piqp is not None) == auto
        piqp, Values = _Piqp(ws, tolerance=None)
        zp, _, _ = piqp.Solve(Values(p_values), q, *args)
        np.testing.assert_allclose(z, zp, atol=1e-6)


@needs_hpipm
def test_a_row_of_fixed_variables_is_checked_not_handed_to_hpipm():
    """A row whose variables are all fixed (an empty slot's KKT rows) is
    not HPIPM's (its IPM stalls on it): within its bounds the QP is solved
    as without it; outside them the solve says which row is infeasible."""
    ws, p_values, q, args, _, _ = _TinyMpc(False)
    z_without, _, _ = ws.Solve(p_values, q, *args)
    ws, p_values, q, args, _, _ = _TinyMpc(False, fixed_row=(1.5, 2.5))
    z, status, _ = ws.Solve(p_values, q, *args)
    assert status == "solved"
    np.testing.assert_allclose(z, z_without, atol=1e-9)
    ws, p_values, q, args, _, _ = _TinyMpc(False, fixed_row=(2.5, 3.0))
    z, status, iterations = ws.Solve(p_values, q, *args)
    assert z is None and iterations == 0
    assert status == "primal_infeasible (a row of fixed variables)"


@needs_hpipm
def test_empty_slots_are_pinned_and_hpipm_solves_every_qp_fast(monkeypatch):
    """One person in three program slots: the two empty slots' positions,
    actions and ORCA multipliers are pinned at their parked rest (what the
    forward simulation gives them), and HPIPM's fast mode then solves every
    stage QP (with them free it stalled on 93 % of them)."""
    from sm2ith_drake.control.prediction.orca_kkt import OrcaKkt

    checked = []
    apply_bounds = OrcaKkt.ApplyBounds

    def Checking(self, lower, upper):
        apply_bounds(self, lower, upper)
        empty = ~self.active
        parked = np.broadcast_to(self.p0[empty], self.p[1:, empty].shape)
        for index, value in ((self.p[1:, empty], parked), (self.a[:, empty], 0.0)):
            np.testing.assert_array_equal(lower[index], value)
            np.testing.assert_array_equal(upper[index], value)
        lam = self.lam[:, empty]
        assert np.all(lower[lam] == 0.0) and np.all(upper[lam] == 0.0)
        checked.append(int(empty.sum()))

    modes = []
    solve = hpipm_library.OcpQp.Solve

    def Recording(self, robust=False, **kw):
        status, iterations = solve(self, robust, **kw)
        modes.append((robust, status))
        return status, iterations

    monkeypatch.setattr(OrcaKkt, "ApplyBounds", Checking)
    monkeypatch.setattr(hpipm_library.OcpQp, "Solve", Recording)
    result = RunSimulation(_Crossing("crossing_ridgeback_ur10_1h"), duration=1.0)
    assert all(r.mode == "solved" for r in result.log.records)
    # Before the first prediction every slot is empty.
    assert checked[-1] == 2 and set(checked) <= {2, 3}
    assert len(modes) >= 10
    assert modes == [(False, "solved")] * len(modes)


def test_auto_is_piqp_where_hpipm_is_missing(monkeypatch):
    """qp_solver auto without HPIPM installed (Python 3.11): PIQP solves
    every stage QP, no error."""
    monkeypatch.setattr(hpipm_library, "Available", lambda: False)
    used = []
    for cls in (HpipmWorkspace, PiqpWorkspace):
        solve = cls.Solve

        def Recording(self, *args, _solve=solve, _name=cls.__name__, **kw):
            used.append(_name)
            return _solve(self, *args, **kw)

        monkeypatch.setattr(cls, "Solve", Recording)
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        scenario_name="crossing_stretch3_1h",
        scenario_text="{controller: {qp_solver: auto}}",
    )
    result = RunSimulation(scenario, duration=0.4)
    assert all(r.mode == "solved" for r in result.log.records)
    assert used and set(used) == {"PiqpWorkspace"}


def test_a_missing_hpipm_says_what_to_install(monkeypatch):
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    hpipm_library.Library.cache_clear()
    try:
        with pytest.raises(hpipm_library.HpipmUnavailable, match=r"\[hpipm\]"):
            hpipm_library.Library()
        assert not hpipm_library.Available()
    finally:
        hpipm_library.Library.cache_clear()


def test_layout_roles_give_each_variable_its_knot():
    layout = VariableLayout(num_positions=2, num_velocities=1, horizon=3)
    slack = layout.AddVariables("slack", (4,))
    role, knot = layout.Roles()
    assert np.all(role[layout.q] == STATE) and np.all(role[layout.u] == INPUT)
    np.testing.assert_array_equal(knot[layout.q[:, 1]], np.arange(4))
    np.testing.assert_array_equal(knot[layout.u[:, 0]], np.arange(3))
    assert np.all(role[slack] == OTHER) and np.all(knot[slack] == -1)
    with pytest.raises(ValueError, match="rows"):
        layout.AddVariables("bad", (2, 1), role=STATE)


def test_batched_solve_matches_numpy_and_rejects_singular_blocks():
    rng = np.random.default_rng(5)
    # General blocks (pivoting needed), and the dynamics' kind: identity
    # plus a few off-diagonal entries.
    general = rng.normal(size=(6, 9, 9))
    dynamics = np.eye(24) + 0.1 * (rng.random((11, 24, 24)) < 0.05)
    for M in (general, dynamics):
        rhs = rng.normal(size=M.shape[:2] + (7,))
        X = solve_batched(M, rhs)
        np.testing.assert_allclose(X, np.linalg.solve(M, rhs), atol=1e-10)
        np.testing.assert_allclose(np.einsum("kij,kjr->kir", M, X), rhs, atol=1e-10)
    singular = general.copy()
    singular[2, :, 4] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        solve_batched(singular, rng.normal(size=(6, 9, 2)))
    bad = general.copy()
    bad[3, 5, 2] = np.nan
    with pytest.raises(np.linalg.LinAlgError):
        solve_batched(bad, rng.normal(size=(6, 9, 2)))


@needs_hpipm
def test_warm_passes_start_from_the_same_steps_solution_only(monkeypatch):
    """controller.rti_warm_start "passes": a stage QP given the token of its
    pattern's last solve starts from that solution (fewer iterations, the
    same solution to the QP's tolerance); any other token starts cold, bit
    for bit as if nothing had been solved before (a solve never depends on
    an earlier control step)."""
    calls, solve = _RecordSolves(monkeypatch)
    RunSimulation(_Crossing("crossing_ridgeback_ur10_2h"), duration=0.6)
    ws, args = calls[-1]
    cold, _, it_cold = solve(ws, *args, warm_token=None)
    step = object()
    first, _, it_first = solve(ws, *args, warm_token=step)
    again, status, it_again = solve(ws, *args, warm_token=step)
    assert status == "solved"
    np.testing.assert_array_equal(first, cold)  # a new token: cold
    assert it_first == it_cold and it_again < it_cold
    # The stage QPs are degenerate: a different start ends elsewhere on the
    # optimal face, within the QP's tolerance (measured up to 4e-3,
    # docs/benchmark-history.md, HPIPM's warm start).
    np.testing.assert_allclose(again, cold, atol=5e-3)
    later, _, it_later = solve(ws, *args, warm_token=object())
    np.testing.assert_array_equal(later, cold)
    assert it_later == it_cold


@needs_hpipm
def test_a_start_point_is_all_a_solve_depends_on(monkeypatch):
    """controller.rti_warm_start "point": a stage QP started from a point
    gives the same solution to the last bit whatever was solved before it
    (every primal entry HPIPM starts from, the slacks included, is
    written), the cold solution to the QP's tolerance, and from the
    solution itself fewer iterations than cold."""
    solve, calls, ws, first, again = _RecordedCrossing(monkeypatch)
    cold, _, it_cold = solve(ws, *first)
    start = np.zeros_like(cold)
    z1, status, it1 = solve(ws, *first, guess=start)
    other, _, _ = solve(ws, *again[-1], guess=np.ones_like(cold))
    assert not np.array_equal(other, z1)
    z2, _, it2 = solve(ws, *first, guess=start)
    assert status == "solved" and it2 == it1
    np.testing.assert_array_equal(z1, z2)
    # Degenerate QPs: another start ends elsewhere on the optimal face,
    # within the QP's tolerance (as with the passes' warm start).
    np.testing.assert_allclose(z1, cold, atol=5e-3)
    from_solution, status, it_solution = solve(ws, *first, guess=cold)
    assert status == "solved" and it_solution < it_cold
    np.testing.assert_allclose(from_solution, cold, atol=5e-3)


@needs_hpipm
def test_the_balanced_mode_is_made_at_its_first_use(monkeypatch):
    """HPIPM's balanced-mode workspace (the retry of a QP the fast mode
    leaves unsolved; auto hands such QPs to PIQP instead) is allocated
    when first needed, and then solves the QP the fast mode was given."""
    solve, _, ws, first, _ = _RecordedCrossing(monkeypatch)
    solve(ws, *first)
    qp = next(s.qp for s in ws._structures.values() if hasattr(s, "qp"))
    assert qp._ipm[1] is None
    status, iterations = qp.Solve(robust=True)
    assert qp._ipm[1] is not None
    assert status == "solved" and iterations > 0
