"""Human prediction inside the MPC: the relaxed-ORCA oracle, the KKT
embedding's Jacobians and consistency, and interactivity."""

import numpy as np
import pytest
from scipy.optimize import minimize

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.prediction.orca_kkt import PredictionConsistency
from sm2ith_drake.control.prediction.slots import FilterPreferredVelocities
from sm2ith_drake.humans import kernels
from sm2ith_drake.humans.half_planes import orca_agent_half_planes
from sm2ith_drake.humans.messages import HumanEstimate, HumanIntents
from sm2ith_drake.humans.relaxed_orca import (
    relaxed_orca_action,
    relaxed_orca_actions,
)
from sm2ith_drake.humans.robot_view import NearestBodies
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import (
    ControllerConfig,
    ObstacleConfig,
    PredictionConfig,
    SafetyConfig,
    TaskConfig,
)


def _GenericSolve(v_pref, v_t, n, rho, no, rho_o, vmax, amax, dt, Ma, Mv):
    """The full relaxed-ORCA QP (a, ζ_a, ζ_v) by SLSQP from several starts."""
    A = len(rho)

    def f(x):
        a, za, zv = x[:2], x[2], x[3:]
        return (a - v_pref) @ (a - v_pref) + Ma * za**2 + Mv * zv @ zv

    cons = [
        {"type": "ineq", "fun": lambda x: vmax**2 - x[:2] @ x[:2]},
        {
            "type": "ineq",
            "fun": lambda x: (dt * amax) ** 2 + x[2] - (x[:2] - v_t) @ (x[:2] - v_t),
        },
        {"type": "ineq", "fun": lambda x: n @ x[:2] - rho + x[3:]},
        {"type": "ineq", "fun": lambda x: x[2:]},
    ]
    if len(rho_o):
        cons.append({"type": "ineq", "fun": lambda x: no @ x[:2] - rho_o})
    best = None
    for start in (np.zeros(2), v_t, v_pref * 0.5):
        x0 = np.concatenate([start, np.ones(1 + A)])
        res = minimize(
            f,
            x0,
            constraints=cons,
            method="SLSQP",
            options={"ftol": 1e-14, "maxiter": 500},
        )
        feasible = all(np.all(c["fun"](res.x) >= -1e-7) for c in cons)
        if feasible and (best is None or res.fun < best.fun):
            best = res
    return best


def test_relaxed_orca_oracle_matches_a_generic_solver():
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(60):
        A = rng.integers(1, 4)
        S = rng.integers(0, 2)
        v_pref = rng.uniform(-1.2, 1.2, 2)
        v_t = rng.uniform(-1.0, 1.0, 2)
        ang = rng.uniform(0, 2 * np.pi, A)
        n = np.column_stack([np.cos(ang), np.sin(ang)])
        rho = rng.uniform(-0.5, 0.8, A)
        ang_o = rng.uniform(0, 2 * np.pi, S)
        no = np.column_stack([np.cos(ang_o), np.sin(ang_o)]).reshape(-1, 2)
        rho_o = rng.uniform(-1.0, -0.1, S)
        args = dict(
            max_speed=1.5, max_accel=2.0, time_step=0.2, slack_weights=(10, 100)
        )
        sol = relaxed_orca_action(
            v_pref, v_t, n, rho, static_normals=no, static_offsets=rho_o, **args
        )
        ref = _GenericSolve(v_pref, v_t, n, rho, no, rho_o, 1.5, 2.0, 0.2, 10, 100)
        if ref is None:
            continue
        # Relative: SLSQP's own optimum is only as good as its tolerance (it
        # stopped with 'positive directional derivative' 3e-7 below ours on
        # one scene with a cost of 11.8).
        assert sol.cost <= ref.fun + 1e-7 * max(1.0, abs(ref.fun))
        np.testing.assert_allclose(sol.velocity, ref.x[:2], atol=2e-4)
        # KKT: stationarity, dual feasibility, complementarity.
        assert sol.stationarity_residual < 1e-6
        assert sol.multiplier_speed >= 0 and np.all(sol.multipliers_static >= 0)
        a = sol.velocity
        assert sol.multiplier_speed * (a @ a - 1.5**2) > -1e-6
        checked += 1
    assert checked >= 50


def _Controller(robot_name, predictor, humans=2, **controller):
    robot = MobileManipulator(robot_name)
    tasks = [TaskConfig(kind="base_position", target=[4.0, 0.0])]
    config = ControllerConfig(**controller)
    prediction = PredictionConfig(predictor=predictor, max_humans=humans)
    return robot, MpcController(
        robot, tasks, config, prediction=prediction, safety=SafetyConfig()
    )


def _HeadOn(count):
    return HumanEstimate(
        ids=np.arange(count),
        positions=np.array([[3.0, 0.1 + 0.8 * j] for j in range(count)]),
        velocities=np.array([[-1.0, 0.0]] * count),
    )


def _KktController(robot_name, humans, **prediction):
    robot = MobileManipulator(robot_name)
    tasks = [TaskConfig(kind="base_position", target=[4.0, 0.0])]
    wall = ObstacleConfig(vertices=[[1.5, -0.8], [4.5, -0.8]])
    return robot, MpcController(
        robot,
        tasks,
        ControllerConfig(),
        prediction=PredictionConfig(
            predictor="orca_kkt", max_humans=humans, **prediction
        ),
        safety=SafetyConfig(),
        obstacles=[wall],
    )


def _SetHumans(c, estimate, predictor_state=None):
    """Hands the controller's predictor a prediction of ``estimate`` (as the
    HumanPredictor system would, without a robot plan to simulate against);
    returns the predictor's next state."""
    model = c.human_predictor
    prediction, state = model.Predict(
        predictor_state or model.InitialState(), estimate=estimate
    )
    c.predictor.SetPrediction(prediction)
    return state


def _Step(c, state, predictor_state, estimate, **kwargs):
    """One control step with the predictor in front, as in the Diagram."""
    model = c.human_predictor
    prediction, predictor_state = model.Predict(
        predictor_state or model.InitialState(),
        estimate=estimate,
        q0=kwargs["q0"],
        nu0=kwargs["nu0"],
        warm_start_inputs=c.WarmStartInputs(state),
    )
    return c.Step(state, prediction=prediction, **kwargs), predictor_state


def _KktPoint(robot, c, humans):
    _SetHumans(c, _HeadOn(humans))
    z = c.WarmStart(c.InitialState(), robot.default_q, np.zeros(robot.num_velocities))
    z = z + np.random.default_rng(0).normal(scale=0.05, size=z.size)
    return z, {"base_position": np.array([4.0, 0.0])}


def test_block_jacobi_jacobian_drops_only_the_neighbour_derivatives():
    """The default (neighbor_derivatives: false) Jacobian of the KKT groups
    is the exact one without each human's derivatives w.r.t. the other
    humans' states; the values g(z) are the same."""
    Js = {}
    for exact in (True, False):
        robot, c = _KktController(
            "ridgeback_ur10", 3, max_neighbors=2, neighbor_derivatives=exact
        )
        z, targets = _KktPoint(robot, c, 3)
        point = c.program.MakePoint(z, targets)
        Js[exact] = [
            (group.Eval(point)[0], group.DenseJacobian(group.Eval(point)[1], z.size))
            for group, _, _ in c.program.extra_constraints[:2]
        ]
    pred = c.predictor
    N, H = pred.N, pred.num_slots
    human_of_column = np.full(z.size, -1)
    human_of_column[pred.p] = np.arange(H)[None, :, None]
    human_of_column[pred.a] = np.arange(H)[None, :, None]
    rows_per_block = (2, 2 * pred.num_multipliers)
    for (g_exact, J_exact), (g_bj, J_bj), per_block in zip(
        Js[True], Js[False], rows_per_block, strict=True
    ):
        np.testing.assert_array_equal(g_exact, g_bj)
        kkt_rows = N * H * per_block
        human_of_row = (np.arange(kkt_rows) // per_block) % H
        cross = (human_of_column[None, :] >= 0) & (
            human_of_column[None, :] != human_of_row[:, None]
        )
        assert np.any(J_exact[:kkt_rows][cross] != 0)
        np.testing.assert_array_equal(J_bj[:kkt_rows][cross], 0.0)
        np.testing.assert_array_equal(
            J_bj[:kkt_rows][~cross], J_exact[:kkt_rows][~cross]
        )
        np.testing.assert_array_equal(J_bj[kkt_rows:], J_exact[kkt_rows:])


def test_neighbours_are_the_closest_approaches_and_the_pattern_follows():
    """Each human's neighbours are the humans that come closest within the
    horizon at constant velocity (not merely the nearest now); with the
    neighbours' derivatives the sparsity pattern changes with them and the
    RTI solver rebuilds its QP, which still solves."""
    robot, c = _KktController(
        "ridgeback_ur10", 3, max_neighbors=1, neighbor_derivatives=True
    )
    # Human 0 at the origin; 1 is nearer now but walks away; 2 is farther
    # but walks straight at 0.
    estimate = HumanEstimate(
        ids=[0, 1, 2],
        positions=[[5.0, 3.0], [6.0, 3.0], [5.0, 5.5]],
        velocities=[[0.0, 0.0], [1.5, 0.0], [0.0, -1.2]],
    )
    _SetHumans(c, estimate)
    assert c.predictor.neighbors[0].tolist() == [2]
    key = c.program.PatternKey()
    kwargs = dict(
        time_now=0.0,
        q0=robot.default_q,
        nu0=np.zeros(robot.num_velocities),
        targets={"base_position": np.array([4.0, 0.0])},
    )
    state, ps = _Step(c, c.InitialState(), None, estimate, **kwargs)
    assert state.record.mode == "solved", state.record.status
    # Human 2 turns away, 1 turns back toward 0: 0's neighbour changes.
    estimate = HumanEstimate(
        ids=[0, 1, 2],
        positions=[[5.0, 3.0], [6.0, 3.0], [5.0, 5.5]],
        velocities=[[0.0, 0.0], [-1.0, 0.0], [0.0, 1.2]],
    )
    state, ps = _Step(c, state, ps, estimate, **kwargs)
    assert c.predictor.neighbors[0].tolist() == [1]
    assert c.program.PatternKey() != key
    assert state.record.mode == "solved", state.record.status
    # Every pair interacts when max_neighbors ≥ H − 1.
    _, full = _KktController("ridgeback_ur10", 3, max_neighbors=5)
    _SetHumans(full, estimate)
    assert full.predictor.neighbors.tolist() == [[1, 2], [0, 2], [0, 1]]


def test_warm_start_is_an_exact_kkt_point():
    robot, c = _Controller("ridgeback_ur10", "orca_kkt", humans=3)
    _SetHumans(c, _HeadOn(3))
    z = c.WarmStart(c.InitialState(), robot.default_q, np.zeros(robot.num_velocities))
    stat, cons, comp = c.predictor.Residuals(z, c.program.layout)
    assert np.max(np.abs(stat)) < 1e-6
    assert np.max(cons) < 1e-9
    assert np.max(np.abs(comp)) < 1e-6
    # The human dynamics hold along the predicted path.
    p, a = z[c.predictor.p], z[c.predictor.a]
    np.testing.assert_allclose(p[1:], p[:-1] + 0.2 * a, atol=1e-12)


def test_past_kkt_steps_each_person_holds_its_last_action():
    """prediction.kkt_steps (SICNav's orca_kkt_horiz): the warm start is an
    exact KKT point over the first T steps and holds the last action after
    them; a solved plan keeps that structure, its first T actions are the
    re-solved relaxed-ORCA QPs', and the QP is smaller."""
    T = 3
    robot, c = _KktController("ridgeback_ur10", 2, kkt_steps=T)
    _, full = _KktController("ridgeback_ur10", 2)
    pred = c.predictor
    assert pred.kkt_steps == T < pred.N
    kkt_rows = sum(
        g.num_rows for g, _, _ in c.program.ConstraintGroups() if "orca_kkt" in g.name
    )
    full_rows = sum(
        g.num_rows
        for g, _, _ in full.program.ConstraintGroups()
        if "orca_kkt" in g.name
    )
    assert kkt_rows < 0.6 * full_rows
    q0, nu0 = robot.default_q, np.zeros(robot.num_velocities)
    _SetHumans(c, _HeadOn(2))
    z = c.WarmStart(c.InitialState(), q0, nu0)
    stat, cons, comp = pred.Residuals(z, c.program.layout)
    assert stat.shape[0] == T
    assert np.max(np.abs(stat)) < 1e-6 and np.max(cons) < 1e-9
    a, lam = z[pred.a], z[pred.lam]
    np.testing.assert_array_equal(a[T:], np.broadcast_to(a[T - 1], a[T:].shape))
    assert np.all(lam[T:] == 0) and np.any(lam[:T] != 0)
    state, _ = _Step(
        c,
        c.InitialState(),
        None,
        _HeadOn(2),
        time_now=0.0,
        q0=q0,
        nu0=nu0,
        targets={"base_position": np.array([4.0, 0.0])},
    )
    assert state.record.mode == "solved", state.record.status
    z = state.last_solution.z
    a = z[pred.a]
    np.testing.assert_allclose(a[T:], np.broadcast_to(a[T - 1], a[T:].shape), atol=1e-6)
    errors = PredictionConsistency(pred, z, c.program.layout)
    assert errors.shape == (T, 2)
    assert np.max(errors) < 1e-2


def _PredictedHuman(predictor, base_target):
    robot, c = _Controller("ridgeback_ur10", predictor, humans=1)
    human = HumanEstimate(ids=[0], positions=[[3.0, 0.0]], velocities=[[-1.0, 0.0]])
    state, _ = _Step(
        c,
        c.InitialState(),
        None,
        human,
        time_now=0.0,
        q0=robot.default_q,
        nu0=np.zeros(robot.num_velocities),
        targets={"base_position": np.asarray(base_target)},
    )
    assert state.record.mode == "solved", state.record.status
    return state.last_solution.human_predictions[:, 0]


def test_predictions_are_interactive():
    """Head-on: the SM²ITH prediction of the human depends on where the robot
    plans to go; the constant-velocity prediction does not."""
    toward = _PredictedHuman("orca_kkt", [4.0, 0.0])
    away = _PredictedHuman("orca_kkt", [-4.0, 0.0])
    assert np.max(np.linalg.norm(toward - away, axis=1)) > 0.05
    cv_toward = _PredictedHuman("cvmm", [4.0, 0.0])
    cv_away = _PredictedHuman("cvmm", [-4.0, 0.0])
    # Pinned by equal bounds, which the interior-point QP meets to its
    # tolerance (differences of ~1e-8 between plans), against > 5 cm above.
    np.testing.assert_allclose(cv_toward, cv_away, atol=1e-6)


def test_agent_half_planes_are_symmetric_for_reciprocal_pairs():
    """ORCA's reciprocity: the u each of two agents computes is opposite, so
    their lines have opposite normals and each agent's current velocity
    violates (or clears) its own line by the same amount."""
    rng = np.random.default_rng(3)
    for _ in range(100):
        pa, pb = rng.uniform(-3, 3, (2, 2))
        va, vb = rng.uniform(-1, 1, (2, 2))
        na, ra = orca_agent_half_planes(
            pa, va, pb, vb, 0.6, 0.5, tau=2.0, time_step=0.2
        )
        nb, rb = orca_agent_half_planes(
            pb, vb, pa, va, 0.6, 0.5, tau=2.0, time_step=0.2
        )
        np.testing.assert_allclose(na, -nb, atol=1e-9)
        np.testing.assert_allclose(na @ va - ra, nb @ vb - rb, atol=1e-9)


def _RandomOrcaBatch(rng, B, A, S):
    """B random relaxed-ORCA instances: current and preferred speeds up to and
    beyond a_max (the speed disc binds), static lines through or near the
    origin, and agent lines far enough out that the slacks carry much of the
    cost."""
    ang = rng.uniform(0, 2 * np.pi, (B, A))
    ang_o = rng.uniform(0, 2 * np.pi, (B, S))
    return dict(
        v_pref=rng.uniform(-2.5, 2.5, (B, 2)),
        v_current=rng.uniform(-1.5, 1.5, (B, 2)),
        normals=np.stack([np.cos(ang), np.sin(ang)], axis=-1),
        offsets=rng.uniform(-0.5, 1.5, (B, A)),
        static_normals=np.stack([np.cos(ang_o), np.sin(ang_o)], axis=-1),
        static_offsets=rng.uniform(-0.8, 0.0, (B, S)),
    )


def _ScalarRow(batch, b, **args):
    return relaxed_orca_action(
        batch["v_pref"][b],
        batch["v_current"][b],
        batch["normals"][b],
        batch["offsets"][b],
        static_normals=batch["static_normals"][b],
        static_offsets=batch["static_offsets"][b],
        **args,
    )


def test_batched_relaxed_orca_matches_the_scalar_solver():
    rng = np.random.default_rng(5)
    rows = speed = static = slack = 0
    for max_speed, weights in ((1.0, (10, 100)), (1.2, (1, 1)), (1.5, (100, 3))):
        args = dict(
            max_speed=max_speed, max_accel=2.0, time_step=0.2, slack_weights=weights
        )
        for A in range(1, 7):
            for S in range(3):
                batch = _RandomOrcaBatch(rng, 6, A, S)
                sol = relaxed_orca_actions(**batch, **args)
                for b in range(6):
                    ref = _ScalarRow(batch, b, **args)
                    np.testing.assert_allclose(
                        sol.velocity[b], ref.velocity, rtol=0, atol=1e-7
                    )
                    for name in (
                        "slack_acceleration",
                        "slack_velocity",
                        "multiplier_speed",
                        "multiplier_acceleration",
                        "multipliers_agents",
                        "multipliers_static",
                    ):
                        np.testing.assert_allclose(
                            getattr(sol, name)[b],
                            getattr(ref, name),
                            rtol=0,
                            atol=1e-6,
                            err_msg=name,
                        )
                    assert sol.stationarity_residual[b] < 1e-6
                    rows += 1
                    speed += ref.multiplier_speed > 1e-6
                    static += np.any(ref.multipliers_static > 1e-6)
                    slack += max(ref.slack_acceleration, *ref.slack_velocity) > 0.3
    assert rows >= 300
    # The constrained and heavily relaxed cases are all well represented.
    assert min(speed, static, slack) >= 30, (speed, static, slack)


def test_batched_relaxed_orca_shapes():
    args = dict(max_speed=1.5, max_accel=2.0, time_step=0.2, slack_weights=(10, 100))
    rng = np.random.default_rng(6)
    # No instances.
    sol = relaxed_orca_actions(**_RandomOrcaBatch(rng, 0, 3, 2), **args)
    assert sol.velocity.shape == (0, 2)
    assert sol.slack_velocity.shape == sol.multipliers_agents.shape == (0, 3)
    assert sol.multipliers_static.shape == (0, 2)
    for name in (
        "slack_acceleration",
        "multiplier_speed",
        "multiplier_acceleration",
        "cost",
        "stationarity_residual",
    ):
        assert getattr(sol, name).shape == (0,)
    # No agent lines (with and without static lines): still the scalar solution.
    for S in (0, 2):
        batch = _RandomOrcaBatch(rng, 8, 0, S)
        sol = relaxed_orca_actions(**batch, **args)
        assert sol.velocity.shape == (8, 2)
        assert sol.slack_velocity.shape == sol.multipliers_agents.shape == (8, 0)
        assert sol.multipliers_static.shape == (8, S)
        assert sol.cost.shape == sol.stationarity_residual.shape == (8,)
        for b in range(8):
            ref = _ScalarRow(batch, b, **args)
            np.testing.assert_allclose(sol.velocity[b], ref.velocity, atol=1e-7)
            np.testing.assert_allclose(
                sol.multiplier_speed[b], ref.multiplier_speed, atol=1e-6
            )
        assert np.all(sol.stationarity_residual < 1e-6)
    # Without static lines at all.
    batch = _RandomOrcaBatch(rng, 4, 2, 0)
    del batch["static_normals"], batch["static_offsets"]
    sol = relaxed_orca_actions(**batch, **args)
    assert sol.multipliers_static.shape == (4, 0)


@pytest.mark.parametrize("robot_name", ["ridgeback_ur10", "stretch3"])
def test_nearest_body_point_derivatives_match_finite_differences(robot_name):
    """The robot as the people see it: the closest point on the nearest
    capsule's axis, differentiated w.r.t. the configuration and the person's
    position (inside the segment, at its clipped ends, on a point-like
    vertical capsule), against central differences."""
    robot, c = _KktController(robot_name, 1)
    pred = c.predictor
    rng = np.random.default_rng(5)
    h = 1e-6
    kinds = set()
    for _ in range(40):
        q = robot.default_q + rng.normal(scale=0.3, size=robot.num_positions)
        P = q[:2] + rng.uniform(-1.5, 1.5, 2)
        view = pred.model.RobotView(q[None], np.zeros((1, robot.num_velocities)))
        body = NearestBodies(view, P[None, None])
        fd_q = np.zeros((2, robot.num_positions))
        for i in range(robot.num_positions):
            qp, qm = q.copy(), q.copy()
            qp[i] += h
            qm[i] -= h
            up = NearestBodies(pred.model.RobotView(qp[None], view.nu), P[None, None])
            um = NearestBodies(pred.model.RobotView(qm[None], view.nu), P[None, None])
            fd_q[:, i] = (up.point - um.point)[0, 0] / (2 * h)
        fd_p = np.zeros((2, 2))
        for i in range(2):
            dp = np.zeros(2)
            dp[i] = h
            up = NearestBodies(view, (P + dp)[None, None])
            um = NearestBodies(view, (P - dp)[None, None])
            fd_p[:, i] = (up.point - um.point)[0, 0] / (2 * h)
        np.testing.assert_allclose(body.d_dq[0, 0], fd_q, atol=1e-6)
        np.testing.assert_allclose(body.d_dp[0, 0], fd_p, atol=1e-6)
        kinds.add("inside" if np.any(np.abs(fd_p) > 1e-3) else "end")
    assert kinds == {"inside", "end"}


@pytest.mark.parametrize("robot_name", ["ridgeback_ur10", "stretch3"])
def test_compiled_step_lines_are_the_vectorized_half_planes(robot_name):
    """The forward simulation's compiled lines (kernels.step_half_planes) are
    OrcaModel.HalfPlanes' to the bit: people near and inside the robot and
    each other, a wall (and its end), random shares toward the robot."""
    robot, c = _KktController(robot_name, 4, max_neighbors=2)
    model = c.predictor.model
    rng = np.random.default_rng(17)
    H, A, S = model.num_slots, model.num_agent_lines, model.num_static_lines
    assert S == 1 and A == 4
    for trial in range(30):
        q = robot.default_q + rng.normal(scale=0.4, size=robot.num_positions)
        nu = rng.uniform(robot.nu_lower, robot.nu_upper)
        view = model.RobotView(q[None], nu[None])
        P = q[:2] + rng.uniform(-2.5 if trial % 3 else -0.6, 2.5, (H, 2))
        V = rng.uniform(-1.5, 1.5, (H, 2))
        neighbors = np.array(
            [rng.permutation([j for j in range(H) if j != h])[:2] for h in range(H)]
        )
        model.SetRobotShares(rng.uniform(0, 1, H))
        expected = model.HalfPlanes(P[None], V[None], view, neighbors)
        got = [
            np.empty((H, A, 2)),
            np.empty((H, A)),
            np.empty((H, S, 2)),
            np.empty((H, S)),
        ]
        kernels.step_half_planes(
            P, V, neighbors, view.p[0], view.v[0], np.ascontiguousarray(view.ends[0]),
            view.radii, model._radius, model._share, model.segments,
            model.human_radius, model.config.tau, model.dt, model.config.tau_obs, *got,
        )  # fmt: skip
        for e, g in zip(expected, got, strict=True):
            np.testing.assert_array_equal(g, e[0])


def test_program_grows_linearly_with_the_number_of_people():
    """With a neighbour cap the SM²ITH program's variables, rows and KKT
    Jacobian nonzeros grow by the same amount for every person added, and
    (block-Jacobi, the default) each person's KKT rows touch only its own
    variables and the robot's."""
    sizes = []
    for H in range(4, 9):
        _, c = _KktController("ridgeback_ur10", H, max_neighbors=2)
        program = c.program
        groups = program.ConstraintGroups()
        sizes.append(
            (
                program.layout.num_variables,
                sum(g.num_rows for g, _, _ in groups),
                sum(g.rows.size for g, _, _ in groups),
            )
        )
    steps = np.diff(np.array(sizes), axis=0)
    assert np.all(steps == steps[0]), sizes
    pred = c.predictor
    owner = np.full(program.layout.num_variables, -1)
    for idx in (pred.p, pred.a, pred.lam):
        owner[idx] = np.arange(pred.num_slots)[None, :, None]
    eq = next(
        g for g, _, _ in c.program.ConstraintGroups() if g.name == "orca_kkt_equalities"
    )
    kkt = eq.rows < eq.num_kkt
    row_owner = (eq.rows[kkt] // 2) % pred.num_slots
    col_owner = owner[eq.cols[kkt]]
    assert np.all((col_owner == -1) | (col_owner == row_owner))


def test_preferred_velocity_is_the_low_pass_filtered_measurement():
    """v_pref of the ORCA model: a new person starts at their measured
    velocity, then follows a first-order filter with the configured time
    constant (closed form: after t seconds of a step change the remaining
    difference is (τ/(τ+Δ))^(t/Δ)); a non-finite measurement keeps the last
    value; the predictor's v_pref is what the controller passes."""
    robot = MobileManipulator("ridgeback_ur10")
    config = ControllerConfig()
    c = MpcController(
        robot,
        [TaskConfig(kind="base_position", target=[4.0, 0.0])],
        config,
        prediction=PredictionConfig(
            predictor="orca_kkt", max_humans=2, preferred_velocity_time_constant=2.0
        ),
        safety=SafetyConfig(),
    )
    alpha = c.period / (2.0 + c.period)
    walking = HumanEstimate(ids=[7], positions=[[5.0, 5.0]], velocities=[[1.0, 0.0]])
    preferred = FilterPreferredVelocities({}, walking, None, alpha)
    np.testing.assert_allclose(preferred[7], [1.0, 0.0])
    turned = HumanEstimate(ids=[7], positions=[[5.0, 5.0]], velocities=[[0.0, 1.0]])
    steps = 10
    for _ in range(steps):
        preferred = FilterPreferredVelocities(preferred, turned, None, alpha)
    decay = (2.0 / (2.0 + c.period)) ** steps
    np.testing.assert_allclose(preferred[7], [decay, 1.0 - decay], atol=1e-12)
    lost = HumanEstimate(ids=[7], positions=[[5.0, 5.0]], velocities=[[np.nan, 0.0]])
    kept = FilterPreferredVelocities(preferred, lost, None, alpha)
    np.testing.assert_array_equal(kept[7], preferred[7])
    # A known intent (simulation only) overrides the measurement.
    intent = HumanIntents(ids=[7], preferred_velocities=[[0.3, -0.4]])
    known = FilterPreferredVelocities(preferred, turned, intent, alpha)
    np.testing.assert_array_equal(known[7], [0.3, -0.4])
    # Through the predictor and a control step, the MPC's v_pref is the
    # filtered value, and the predictor remembers it in its state.
    model = c.human_predictor
    ps = model.InitialState()
    ps.preferred_velocities = dict(preferred)
    new, ps = _Step(
        c,
        c.InitialState(),
        ps,
        turned,
        time_now=0.0,
        q0=robot.default_q,
        nu0=np.zeros(robot.num_velocities),
        targets={"base_position": np.array([4.0, 0.0])},
    )
    assert new.record.mode == "solved", new.record.status
    filtered = preferred[7] + alpha * (np.array([0.0, 1.0]) - preferred[7])
    np.testing.assert_allclose(ps.preferred_velocities[7], filtered)
    slot = int(np.nonzero(c.predictor.slot_ids == 7)[0][0])
    np.testing.assert_allclose(c.predictor.v_pref[slot], filtered)
    assert c.predictor.v_pref[slot][0] > 0.05  # not the latest measurement


def test_guard_holds_exactly_the_people_who_deviate_from_the_last_plan():
    """UpdateGuards: a person is guarded for hold_steps from a step where
    their measured position is farther than the deviation from where the
    last plan predicted them; unpredicted people are not judged; deviation
    0 guards everyone."""
    from types import SimpleNamespace

    from sm2ith_drake.control.prediction.slots import PredictedNow, UpdateGuards

    solution = SimpleNamespace(
        success=True,
        human_slot_ids=np.array([7, -1, 9]),
        human_predictions=np.array(
            [[[0.0, 0.0], [5.0, 5.0], [1.0, 0.0]], [[0.2, 0.0], [5.0, 5.0], [1.0, 0.2]]]
        ),
    )
    predicted = PredictedNow(solution, elapsed=0.1, time_step=0.2)
    assert set(predicted) == {7, 9}
    np.testing.assert_allclose(predicted[7], [0.1, 0.0])
    np.testing.assert_allclose(predicted[9], [1.0, 0.1])
    assert PredictedNow(SimpleNamespace(success=False), 0.1, 0.2) == {}

    def estimate(positions):
        ids = np.array([7, 9, 11])
        return HumanEstimate(
            ids=ids,
            positions=np.array(positions, dtype=float),
            velocities=np.zeros((3, 2)),
        )

    # 7 is where predicted, 9 is 0.2 m off, 11 was not predicted.
    guards = UpdateGuards(
        {},
        estimate([[0.1, 0.01], [1.2, 0.1], [3.0, 3.0]]),
        predicted,
        deviation=0.05,
        hold_steps=3,
    )
    assert guards == {9: 3}
    # Back on the prediction: counts down, then released.
    on_track = estimate([[0.1, 0.0], [1.0, 0.1], [3.0, 3.0]])
    for left in (2, 1):
        guards = UpdateGuards(guards, on_track, predicted, deviation=0.05, hold_steps=3)
        assert guards == {9: left}
    assert UpdateGuards(guards, on_track, predicted, deviation=0.05, hold_steps=3) == {}
    everyone = UpdateGuards({}, on_track, {}, deviation=0.0, hold_steps=2)
    assert everyone == {7: 2, 9: 2, 11: 2}
    # Within the guard gap of the robot: held whatever the prediction says.
    close = UpdateGuards(
        {}, on_track, predicted, deviation=0.05, hold_steps=3, close=[11]
    )
    assert close == {11: 3}


def test_guard_holds_the_people_inside_the_guard_gap():
    """HumanPredictorModel: with guard_gap 0.1 m a person measured 0.05 m
    from the robot's nearest body is guarded even with no plan to judge
    them against, a person 0.5 m away is not; guard_gap 0 or a non-finite
    robot state guards nobody."""
    from sm2ith_drake.humans.robot_view import HumanDistances

    robot = MobileManipulator("stretch3")
    q0 = np.asarray(robot.default_q, dtype=float)

    def Gap(x):
        return HumanDistances(robot, q0[None], np.array([[[x, 0.0]]]))[0, 0] - 0.3

    def At(gap):  # the point on the base's x axis with this gap (bisection)
        lo, hi = 0.0, 5.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if Gap(mid) < gap else (lo, mid)
        return [lo, 0.0]

    estimate = HumanEstimate(
        ids=np.array([4, 5]),
        positions=np.array([At(0.05), [At(0.5)[0], 0.0]]),
        velocities=np.zeros((2, 2)),
    )

    def Guards(guard_gap, q):
        model = _GuardModel(robot, 2, guard_gap=guard_gap)
        prediction, state = model.Predict(
            model.InitialState(), estimate=estimate, q0=q, nu0=np.zeros(3)
        )
        assert state.guard_steps == prediction.guard_steps_by_id
        return prediction.guard_steps_by_id

    assert Guards(0.1, q0) == {4: 5}
    assert Guards(0.0, q0) == {}
    assert Guards(0.1, np.full_like(q0, np.nan)) == {}


def _GuardModel(robot, max_humans, **guard):
    """An ORCA-KKT HumanPredictorModel with the guard's deviation rule (0.05
    m, held 1 s) and ``guard`` (guard_gap, guard_approach)."""
    from sm2ith_drake.control.prediction.predict import HumanPredictorModel

    return HumanPredictorModel(
        PredictionConfig(predictor="orca_kkt", max_humans=max_humans),
        horizon=10,
        time_step=0.2,
        control_period=0.2,
        robot=robot,
        guard_deviation=0.05,
        guard_hold=1.0,
        **guard,
    )


def test_guard_approach_holds_only_the_people_walking_toward_the_robot():
    """HumanPredictorModel: with guard_gap 0.3 m and guard_approach 0.2
    m/s, of three people measured 0.1 m from the robot's nearest body the
    one walking at it at 0.5 m/s is guarded; the one standing (on the
    other side, also inside the gap) and the one walking away are not;
    guard_approach 0 guards all three."""
    from sm2ith_drake.humans.robot_view import HumanDistances

    robot = MobileManipulator("stretch3")
    q0 = np.asarray(robot.default_q, dtype=float)

    def Gap(y):
        return HumanDistances(robot, q0[None], np.array([[[0.0, y]]]))[0, 0] - 0.3

    lo, hi = 0.0, 5.0  # the point on the base's +y axis 0.1 m out (bisection)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if Gap(mid) < 0.1 else (lo, mid)
    y = lo
    estimate = HumanEstimate(
        ids=np.array([1, 2, 3]),
        positions=np.array([[0.0, y], [0.0, -y], [0.0, y]]),
        velocities=np.array([[0.0, -0.5], [0.0, 0.0], [0.0, 0.5]]),
    )

    def Guarded(approach):
        model = _GuardModel(robot, 3, guard_gap=0.3, guard_approach=approach)
        prediction, _ = model.Predict(
            model.InitialState(), estimate=estimate, q0=q0, nu0=np.zeros(3)
        )
        return set(prediction.guard_steps_by_id)

    assert Gap(-y) < 0.3  # the standing person is inside the gap too
    assert Guarded(0.2) == {1}
    assert Guarded(0.0) == {1, 2, 3}
