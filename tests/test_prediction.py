"""Human prediction inside the MPC: the relaxed-ORCA oracle, the KKT
embedding's Jacobians and consistency, and interactivity."""

import numpy as np
import pytest
from scipy.optimize import minimize

from sm2ith_drake.control.controller import MpcController
from sm2ith_drake.humans.orca_kkt import orca_agent_half_planes
from sm2ith_drake.humans.predictors import HumanEstimate
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_action
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import (
    ControllerConfig,
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
        assert sol.cost <= ref.fun + 1e-7
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


@pytest.mark.parametrize("robot_name", ["ridgeback_ur10", "stretch3"])
def test_kkt_group_jacobians_match_finite_differences(robot_name):
    robot, c = _Controller(robot_name, "orca_kkt", humans=2)
    c.predictor.SetHumans(_HeadOn(2))
    state = c.InitialState()
    z = c.WarmStart(state, robot.default_q, np.zeros(robot.num_velocities))
    z = z + np.random.default_rng(0).normal(scale=0.05, size=z.size)
    program = c.program
    targets = {"base_position": np.array([4.0, 0.0])}
    for group, _, _ in program.extra_constraints:
        g0, vals = group.Eval(program.MakePoint(z, targets))
        J = group.DenseJacobian(vals, z.size)
        cols = np.unique(group.cols)
        h = 1e-6
        for i in np.arange(z.size):
            zp, zm = z.copy(), z.copy()
            zp[i] += h
            zm[i] -= h
            fd = (
                group.Eval(program.MakePoint(zp, targets))[0]
                - group.Eval(program.MakePoint(zm, targets))[0]
            ) / (2 * h)
            if i not in cols:
                assert np.max(np.abs(fd)) < 1e-6, (group.name, i)
            else:
                np.testing.assert_allclose(
                    J[:, i], fd, atol=1e-5, err_msg=f"{group.name} column {i}"
                )


def test_warm_start_is_an_exact_kkt_point():
    robot, c = _Controller("ridgeback_ur10", "orca_kkt", humans=3)
    c.predictor.SetHumans(_HeadOn(3))
    z = c.WarmStart(c.InitialState(), robot.default_q, np.zeros(robot.num_velocities))
    stat, cons, comp = c.predictor.Residuals(z, c.program.layout)
    assert np.max(np.abs(stat)) < 1e-6
    assert np.max(cons) < 1e-9
    assert np.max(np.abs(comp)) < 1e-6
    # The human dynamics hold along the predicted path.
    p, a = z[c.predictor.p], z[c.predictor.a]
    np.testing.assert_allclose(p[1:], p[:-1] + 0.2 * a, atol=1e-12)


def _PredictedHuman(predictor, base_target):
    robot, c = _Controller("ridgeback_ur10", predictor, humans=1)
    human = HumanEstimate(ids=[0], positions=[[3.0, 0.0]], velocities=[[-1.0, 0.0]])
    state = c.Step(
        c.InitialState(),
        time_now=0.0,
        q0=robot.default_q,
        nu0=np.zeros(robot.num_velocities),
        targets={"base_position": np.asarray(base_target)},
        humans=human,
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
    np.testing.assert_allclose(cv_toward, cv_away, atol=1e-9)


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
