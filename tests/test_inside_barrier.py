"""safety.inside_barrier: the DT-CBF rows where the plan is already inside a
barrier's margin (h_k < 0 at the linearization point).

"decay" (the default) keeps the paper's row h_{k+1} − (1 − γ) h_k ≥ 0
everywhere; "exit" asks h_{k+1} ≥ 0 where h_k < 0, so a row's slack is the
depth at k + 1. Both give the same rows wherever h ≥ 0."""

import numpy as np

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import (
    ControllerConfig,
    ObstacleConfig,
    PredictionConfig,
    SafetyConfig,
    TaskConfig,
)
from sm2ith_drake.scenario_loader import LoadScenarioAndRobot

HORIZON = 3
STEP = 1e-6


def _Controller(inside, positions, guard_gamma=0.0, config=None, guard_inside="exit"):
    """A Stretch 3 among people at ``positions`` (ORCA-KKT slots, the guard
    on 2 steps, with ``guard_gamma``) beside a wall, and a perturbed warm
    start; ``config``: the ControllerConfig (default: a horizon of
    HORIZON)."""
    robot = MobileManipulator("stretch3")
    c = MpcController(
        robot,
        [TaskConfig(kind="base_position", target=[2.0, 0.0])],
        config or ControllerConfig(horizon=HORIZON),
        prediction=PredictionConfig(predictor="orca_kkt", max_humans=len(positions)),
        safety=SafetyConfig(
            guard_steps=2,
            inside_barrier=inside,
            guard_gamma=guard_gamma,
            guard_inside=guard_inside,
        ),
        obstacles=[ObstacleConfig(vertices=[[-1.0, -0.45], [1.0, -0.45]])],
    )
    q0 = robot.default_q.copy()
    nu0 = np.zeros(robot.num_velocities)
    nu0[:2] = [0.2, 0.4]
    model = c.human_predictor
    prediction, _ = model.Predict(
        model.InitialState(),
        estimate=HumanEstimate(
            ids=list(range(len(positions))),
            positions=positions,
            velocities=[[-0.3, 0.1]] * len(positions),
        ),
        q0=q0,
        nu0=nu0,
        warm_start_inputs=c.WarmStartInputs(c.InitialState()),
    )
    c.predictor.SetPrediction(prediction)
    c.program.VariableBounds(q0, nu0)  # sets the guard
    z = c.WarmStart(c.InitialState(), q0, nu0)
    z = z + np.random.default_rng(3).normal(scale=1e-2, size=z.size)
    targets = {t.name: np.asarray(t.target, dtype=float) for t in c.tasks}
    return c, c.program.MakePoint(z, targets), z, targets


# One person well clear of the robot, one inside the margin of its body.
POSITIONS = [[2.5, 1.5], [0.35, 0.25]]


def _RowsByKind(cbf, point):
    """Rows' values and Jacobians of one DT-CBF group at ``point``, with the
    barriers h of the people's and walls' rows at every knot."""
    g, vals = cbf.Eval(point)
    J = cbf.DenseJacobian(vals, point.z.size)
    h_hum, _, _, h_obs, _ = cbf.Barriers(point)
    return g, J, h_hum, h_obs


def _JacobianAndDifferences(c, point, z, targets):
    """The DT-CBF group's analytic Jacobian at ``point`` and its central
    differences in every column the group reads."""
    cbf = c.program.cbf
    J = cbf.DenseJacobian(cbf.Eval(point)[1], z.size)
    F = np.zeros_like(J)
    for i in np.unique(cbf.cols):
        zp, zm = z.copy(), z.copy()
        zp[i] += STEP
        zm[i] -= STEP
        gp = cbf.Eval(c.program.MakePoint(zp, targets))[0]
        gm = cbf.Eval(c.program.MakePoint(zm, targets))[0]
        F[:, i] = (gp - gm) / (2 * STEP)
    return J, F


def test_exit_rows_ask_for_the_barrier_where_the_plan_is_inside():
    decay, point, _, _ = _Controller("decay", POSITIONS)
    exit_, point_exit, _, _ = _Controller("exit", POSITIONS)
    g_d, J_d, h_hum, h_obs = _RowsByKind(decay.program.cbf, point)
    g_e, J_e, _, _ = _RowsByKind(exit_.program.cbf, point_exit)
    np.testing.assert_array_equal(point.z, point_exit.z)
    N, a = HORIZON, 1.0 - decay.safety.gamma
    slack = point.z[decay.program.cbf.slack]
    main = N * decay.program.cbf.rows_per_step
    h = np.concatenate(
        [h_hum.reshape(N + 1, -1), h_obs.reshape(N + 1, -1)], axis=1
    )  # per knot, in the rows' order
    inside = h[:-1] < 0
    # The scene has rows of both kinds.
    assert inside.any() and (~inside).any()
    inside, h_next, h_now = inside.ravel(), h[1:].ravel(), h[:-1].ravel()
    np.testing.assert_allclose(
        g_d[:main] - slack[:main], h_next - a * h_now, atol=1e-12
    )
    expected = np.where(inside, h_next, h_next - a * h_now)
    np.testing.assert_allclose(g_e[:main] - slack[:main], expected, atol=1e-12)
    # Outside the margin the rows and their Jacobians are the paper's.
    rows = np.nonzero(~inside)[0]
    np.testing.assert_array_equal(g_e[rows], g_d[rows])
    np.testing.assert_array_equal(J_e[rows], J_d[rows])
    # Inside, a row no longer reads knot k's robot state.
    q_now = decay.program.layout.q[:-1]  # (N, n): knot k of step k
    per_step = decay.program.cbf.rows_per_step
    for r in np.nonzero(inside)[0]:
        k = r // per_step
        assert np.all(J_e[r, q_now[k]] == 0.0)
        assert np.any(J_d[r, q_now[k]] != 0.0)


def test_exit_rows_and_guard_rows_have_consistent_jacobians():
    """The exit rows' analytic Jacobian against central differences, at a
    point where no h_k is near 0 (the rows switch form there)."""
    c, point, z, targets = _Controller("exit", POSITIONS)
    cbf = c.program.cbf
    assert cbf.num_guard > 0
    _, _, h_hum, h_obs = _RowsByKind(cbf, point)
    assert min(np.abs(h_hum).min(), np.abs(h_obs).min()) > 1e-3
    J, F = _JacobianAndDifferences(c, point, z, targets)
    np.testing.assert_allclose(J, F, atol=2e-6)


def test_guard_rows_switch_form_inside_the_margin_too():
    """The guard's rows (people moving on at their measured velocity) follow
    the same rule: with the person inside the margin at knot 0, the guard's
    first row reads h_1 alone."""
    decay, point, _, _ = _Controller("decay", POSITIONS)
    exit_, point_exit, _, _ = _Controller("exit", POSITIONS)
    cbf_d, cbf_e = decay.program.cbf, exit_.program.cbf
    g_d, _ = cbf_d.Eval(point)
    g_e, _ = cbf_e.Eval(point_exit)
    guard = slice(cbf_d.num_rows - cbf_d.num_guard, cbf_d.num_rows)
    assert np.any(g_e[guard] != g_d[guard])
    # Where the guard's rows differ, exit asks more of the plan (h_k < 0).
    differ = g_e[guard] != g_d[guard]
    assert np.all(g_e[guard][differ] < g_d[guard][differ])


def _GuardRowsOfBoth(c_a, c_b, z, targets):
    """Two controllers' DT-CBF rows at the same z with the slacks at 0: the
    people's and walls' rows (asserted equal), then each one's guard rows
    (guard steps, ·)."""
    cbf_a, cbf_b = c_a.program.cbf, c_b.program.cbf
    z = z.copy()
    z[cbf_a.slack] = 0.0
    g_a, _ = cbf_a.Eval(c_a.program.MakePoint(z, targets))
    g_b, _ = cbf_b.Eval(c_b.program.MakePoint(z, targets))
    main = cbf_a.num_rows - cbf_a.num_guard
    np.testing.assert_array_equal(g_a[:main], g_b[:main])
    steps = cbf_a.guard_steps
    return g_a[main:].reshape(steps, -1), g_b[main:].reshape(steps, -1)


def test_guard_gamma_one_asks_only_that_the_guarded_barrier_holds():
    """safety.guard_gamma: with 1 each guard row reads h_{k+1} of the person
    moving on at their measured velocity; with the default (safety.gamma)
    it reads h_{k+1} − (1 − γ) h_k. So with the slacks at 0 the default's
    rows minus gamma 1's are −(1 − γ) h_k, where h_k (k ≥ 1) is gamma 1's
    row of the step before; the first rows differ by −(1 − γ) h_0. The
    people's and walls' rows are the same."""
    c_d, point, z, targets = _Controller("decay", POSITIONS)
    c_1, _, _, _ = _Controller("decay", POSITIONS, guard_gamma=1.0)
    cbf_d, cbf_1 = c_d.program.cbf, c_1.program.cbf
    assert cbf_1.guard_gamma == 1.0 and cbf_d.guard_gamma == c_d.safety.gamma
    rows_d, rows_1 = _GuardRowsOfBoth(c_d, c_1, z, targets)
    a = 1.0 - c_d.safety.gamma
    np.testing.assert_allclose(rows_d[1:] - rows_1[1:], -a * rows_1[:-1], atol=1e-12)
    assert np.all(rows_d[0] != rows_1[0])


def test_guard_gamma_rows_have_consistent_jacobians():
    """The guard rows with guard_gamma 1 against central differences."""
    c, point, z, targets = _Controller("decay", POSITIONS, guard_gamma=1.0)
    cbf = c.program.cbf
    J, F = _JacobianAndDifferences(c, point, z, targets)
    guard = slice(cbf.num_rows - cbf.num_guard, cbf.num_rows)
    np.testing.assert_allclose(J[guard], F[guard], atol=2e-6)


def test_guard_hold_rows_ask_for_no_closer_inside_the_margin():
    """safety.guard_inside "hold": a guard row whose h_k < 0 at the point
    (inside the margin of the person moving on) reads h_{k+1} − h_k, so it
    asks for no closer rather than out at once (h_{k+1}, guard_gamma 1);
    the others are the same, and so are the people's and walls' rows.
    With the slacks at 0 the hold rows minus the exit rows are −h_k: the
    exit row of the step before (k ≥ 1), −h_0 for the first."""
    c_e, point, z, targets = _Controller("decay", POSITIONS, guard_gamma=1.0)
    c_h, _, _, _ = _Controller("decay", POSITIONS, guard_gamma=1.0, guard_inside="hold")
    assert c_h.program.cbf.guard_inside == "hold"
    rows_e, rows_h = _GuardRowsOfBoth(c_e, c_h, z, targets)  # rows_e: h_{k+1}
    inside = rows_e[:-1] < 0  # h_k < 0 for k ≥ 1
    assert inside.any() and (~inside).any()
    np.testing.assert_allclose(
        rows_h[1:], np.where(inside, rows_e[1:] - rows_e[:-1], rows_e[1:]), atol=1e-12
    )
    # The person inside the margin at knot 0: a first row no closer than h_0.
    first = rows_h[0] != rows_e[0]
    assert first.any() and np.all(rows_h[0][first] > rows_e[0][first])


def test_guard_hold_rows_have_consistent_jacobians():
    """The hold rows against central differences, at a point where no h_k
    is near 0 (the rows switch form there)."""
    c, point, z, targets = _Controller(
        "decay", POSITIONS, guard_gamma=1.0, guard_inside="hold"
    )
    cbf = c.program.cbf
    guard = slice(cbf.num_rows - cbf.num_guard, cbf.num_rows)
    J, F = _JacobianAndDifferences(c, point, z, targets)
    np.testing.assert_allclose(J[guard], F[guard], atol=2e-6)


def test_the_scenario_option_reaches_the_barrier_rows():
    """safety.inside_barrier from a scenario file to the DT-CBF group (a bad
    value is refused by the scenario checks: tests/test_bad_input.py)."""
    scenario, robot = LoadScenarioAndRobot(
        filename=str(GetDiagramsDir() / "doorway.scenarios.yaml"),
        scenario_name="doorway_stretch3",
        scenario_text="{safety: {inside_barrier: exit, guard_inside: hold}}",
    )
    controller = MpcController.FromScenario(robot, scenario)
    assert controller.program.cbf.inside == "exit"
    assert controller.program.cbf.guard_inside == "hold"
    assert MpcController(robot, scenario.tasks, scenario.controller).program.cbf is None
