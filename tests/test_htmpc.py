"""The hierarchical MPC: strict priority, the lexicographic invariant, the
weighted-sum baseline, fallbacks, and the RTI against the full NLP."""

import numpy as np
import pytest

from sm2ith_drake.control import hpipm_library
from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.stage_problem import StageResult
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario, MakeRobot

CONFLICT = GetDiagramsDir() / "conflict.scenarios.yaml"
REACH = GetDiagramsDir() / "reach.scenarios.yaml"
DURATION = 8.0


def _run(name, text="{}", filename=CONFLICT, duration=DURATION):
    scenario = LoadScenario(filename=filename, scenario_name=name, scenario_text=text)
    return scenario, RunSimulation(scenario, duration=duration)


def _final_error(result, task):
    return float(np.linalg.norm(result.log.task_errors[task][-1]))


@pytest.fixture(scope="module")
def conflict_runs():
    runs = {}
    for name in [
        "conflict_ee_over_base",
        "conflict_base_over_ee",
        "conflict_weighted_sum",
    ]:
        runs[name] = _run(name)[1]
    # Single-task optima: each task alone.
    runs["ee_only"] = _run(
        "conflict_ee_over_base",
        "{tasks: [{kind: ee_position, target: [1.2, 0.0, 0.9]}]}",
    )[1]
    runs["base_only"] = _run(
        "conflict_ee_over_base", "{tasks: [{kind: base_position, target: [4.0, 0.0]}]}"
    )[1]
    return runs


def test_strict_priority_on_conflict(conflict_runs):
    r = conflict_runs
    ee_opt = _final_error(r["ee_only"], "ee_position")
    base_opt = _final_error(r["base_only"], "base_position")
    # Each task alone is (almost) achievable.
    assert ee_opt < 0.02 and base_opt < 0.05
    # EE ≥ base: the EE stays at its single-task optimum, the base yields.
    ee_first = r["conflict_ee_over_base"]
    assert _final_error(ee_first, "ee_position") <= ee_opt + 0.01
    assert _final_error(ee_first, "base_position") > 1.0
    # base ≥ EE: the reverse.
    base_first = r["conflict_base_over_ee"]
    assert _final_error(base_first, "base_position") <= base_opt + 0.01
    assert _final_error(base_first, "ee_position") > 1.0


def test_weighted_sum_trades_off(conflict_runs):
    r = conflict_runs
    ws = r["conflict_weighted_sum"]
    ee_ws = _final_error(ws, "ee_position")
    base_ws = _final_error(ws, "base_position")
    assert ee_ws > _final_error(r["conflict_ee_over_base"], "ee_position") + 0.1
    assert base_ws > _final_error(r["conflict_base_over_ee"], "base_position") + 0.1
    # ...and neither task is simply dropped.
    assert ee_ws < _final_error(r["conflict_base_over_ee"], "ee_position") - 0.1
    assert base_ws < _final_error(r["conflict_ee_over_base"], "base_position") - 0.1


def _check_lexicographic_invariant(log, tasks, tol):
    checked = 0
    for stages in log.stage_errors:
        if stages is None:
            continue
        for ell in range(1, len(stages)):
            for i in range(ell):
                name = tasks[i]
                e_star = np.abs(stages[i][name])
                e_ell = np.abs(stages[ell][name])
                # Solver accuracy (PIQP eps 1e-7) on top of the tolerance.
                assert np.all(e_ell <= e_star + tol + 1e-4), (ell, name)
                checked += 1
    return checked


def test_lexicographic_invariant_every_step(conflict_runs):
    scenario = LoadScenario(filename=CONFLICT, scenario_name="conflict_ee_over_base")
    tol = scenario.controller.lexicographic_tolerance
    for name in ["conflict_ee_over_base", "conflict_base_over_ee"]:
        log = conflict_runs[name].log
        tasks = list(log.task_errors)
        assert _check_lexicographic_invariant(log, tasks, tol) >= 30


def test_lexicographic_invariant_five_levels():
    scenario, result = _run("everything", duration=3.0)
    tasks = [t.name or t.kind for t in scenario.tasks]
    assert (
        _check_lexicographic_invariant(
            result.log, tasks, scenario.controller.lexicographic_tolerance
        )
        >= 10
    )


def test_limits_never_exceeded(conflict_runs):
    for result in conflict_runs.values():
        assert result.metrics["limit_violations"] == 0
        assert result.metrics["solver_failures"] == 0


@pytest.mark.parametrize("qp_solver, max_iter", [("piqp", 1), ("piqp", 0), ("auto", 1)])
def test_forced_solver_failure_brakes(qp_solver, max_iter):
    # A robot already moving, with QP solvers that cannot succeed (auto: the
    # QPs HPIPM does not solve go to PIQP, which cannot either).
    if qp_solver != "piqp" and not hpipm_library.Available():
        pytest.skip("HPIPM is not installed (Python < 3.12)")
    options = f"{{PIQP: {{max_iter: {max_iter}}}, HPIPM: {{iter_max: {max_iter}}}}}"
    text = (
        f"{{controller: {{qp_solver: {qp_solver}, "
        f"solver_options: {{options: {options}}}}}, "
        "robot: {initial_nu: [0.5, 0.0, 0.0, 0, 0, 0, 0, 0, 0]}}"
    )
    scenario, result = _run("conflict_ee_over_base", text, duration=2.0)
    c = result.log.counters
    assert c.steps >= 10
    assert c.solver_failures == c.steps
    assert c.fallbacks == c.steps and c.braking_fallbacks == c.steps
    modes = {r.mode for r in result.log.records}
    assert modes == {"brake"}
    # The robot brakes to a stop within its deceleration limit.
    final_nu = result.log.states[-1][9:]
    assert np.allclose(final_nu, 0.0, atol=1e-9)


def test_rti_converges_to_the_nlp_solution():
    """Many RTI iterations on one stage reach the SNOPT solution of the same
    nonlinear program (the validation path)."""
    scenario = LoadScenario(
        filename=REACH,
        scenario_name="ridgeback_ur10_reach",
        scenario_text="{tasks: [{kind: ee_position, target: [1.0, 0.5, 0.8]}]}",
    )
    robot = MakeRobot(scenario)
    q0 = robot.default_q.copy()
    nu0 = np.zeros(robot.num_velocities)
    targets = {"ee_position": np.array([1.0, 0.5, 0.8])}
    plans = {}
    # The proximal damping does not move the fixed point of the iteration,
    # only how fast it is reached; a light one converges in few iterations.
    scenario.controller.rti_proximal_weight = 1e-3
    for solver, iters in [("rti", 30), ("snopt", 1)]:
        scenario.controller.solver = solver
        scenario.controller.rti_iterations = iters
        controller = MpcController(robot, scenario.tasks, scenario.controller)
        state = controller.InitialState()
        z0 = controller.WarmStart(state, q0, nu0)
        sol = controller.solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z0)
        assert sol.success, sol.status
        plans[solver] = sol
    # The same plan (measured: 8e-7 m apart).
    assert np.max(np.abs(plans["rti"].p_WE - plans["snopt"].p_WE)) < 1e-4
    assert np.max(np.abs(plans["rti"].z - plans["snopt"].z)) < 1e-3


class _RecordingStageSolver:
    """A stage solver that records the plans of the one it wraps."""

    def __init__(self, solver):
        self.solver = solver
        self.plans = []

    def Solve(self, point, **kwargs):
        result = self.solver.Solve(point, **kwargs)
        self.plans.append(result.z.copy())
        return result


class _FailingStageSolver:
    """A stage solver that always fails."""

    def Solve(self, point, **kwargs):
        return StageResult(z=point.z, success=False, status="forced", iterations=0)


def test_failed_lower_stage_keeps_the_plan_above():
    scenario = LoadScenario(filename=CONFLICT, scenario_name="conflict_ee_over_base")
    robot = MakeRobot(scenario)
    controller = MpcController(robot, scenario.tasks, scenario.controller)
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    solver = controller.solver
    z0 = controller.WarmStart(controller.InitialState(), q0, nu0)
    full = solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z0)
    assert full.success and full.status == "solved" and len(full.stages) == 2

    # Through the solver's declared seam: the EE stage recorded, the base
    # stage forced to fail.
    recording = _RecordingStageSolver(solver.stage_solvers[0])
    solver.stage_solvers[0] = recording
    solver.stage_solvers[1] = _FailingStageSolver()
    partial = solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z0)
    assert partial.success
    assert partial.status.startswith("solved through 'ee_position'")
    assert len(partial.stages) == 1
    # The plan is the EE stage's (its last pass), not the base stage's.
    assert np.array_equal(partial.z, recording.plans[-1])
    assert not np.allclose(partial.z, full.z)

    # The top stage failing is a failed solve (the controller falls back).
    solver.stage_solvers[0] = _FailingStageSolver()
    failed = solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z0)
    assert not failed.success and "forced" in failed.status


def test_joint_too_fast_to_stop_before_its_limit_is_braked_not_infeasible():
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name="stretch3_reach",
    )
    robot = MakeRobot(scenario)
    controller = MpcController(robot, scenario.tasks, scenario.controller)
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    arm = 4  # joint_arm (telescoping): q index 4, ν index 3
    q0[arm] = robot.q_lower[arm] + 0.03
    nu0[arm - 1] = robot.nu_lower[arm - 1]  # full speed toward the limit
    stop = nu0[arm - 1] ** 2 / (2 * robot.nudot_upper[arm - 1])
    assert stop > 0.03  # it cannot stop before the limit

    state = controller.Step(
        controller.InitialState(), time_now=0.0, q0=q0, nu0=nu0, targets=targets
    )
    assert state.record.mode == "solved", state.record.status
    # The plan brakes the joint at full deceleration.
    assert state.plan.nu[1][arm - 1] > nu0[arm - 1]
    assert state.command_u[arm - 1] == pytest.approx(robot.nudot_upper[arm - 1])

    # Without the braking-consistent bounds the same step is infeasible.
    controller.program.braking_consistent_bounds = False
    state = controller.Step(
        controller.InitialState(), time_now=0.0, q0=q0, nu0=nu0, targets=targets
    )
    assert state.record.mode != "solved"


def test_second_rti_pass_runs_exactly_when_predictions_have_not_converged():
    """With rti_iterations: 2 and a prediction tolerance, a step stops after
    one pass only if its predicted human actions are within the tolerance
    of the re-solved relaxed-ORCA QPs; tolerance 0 always runs both passes."""
    crossing = GetDiagramsDir() / "crossing.scenarios.yaml"
    tol = 5e-3
    _, adaptive = _run(
        "crossing_ridgeback_ur10_3h",
        "{controller: {check_predictions: true, rti_iterations: 2, "
        f"rti_prediction_tolerance: {tol}}}}}",
        filename=crossing,
        duration=4.0,
    )
    solved = [r for r in adaptive.log.records if r.mode == "solved"]
    one = [r for r in solved if r.passes == 1]
    assert one and len(one) < len(solved)  # both cases occur here
    for r in one:  # (no one tracked yet: nothing to predict)
        assert np.all(r.prediction_errors <= tol)
    assert any(r.prediction_errors.size for r in one)
    _, always = _run(
        "crossing_ridgeback_ur10_3h",
        "{controller: {rti_iterations: 2, rti_prediction_tolerance: 0}}",
        filename=crossing,
        duration=2.0,
    )
    assert {r.passes for r in always.log.records if r.mode == "solved"} == {2}


@pytest.mark.parametrize("early", [False, True])
def test_early_pass_check_skips_the_lower_stages_of_a_pass_that_failed(
    early, monkeypatch
):
    """With rti_prediction_tolerance 0 every pass fails the pass rule, so
    with rti_early_pass_check the first pass stops after its first stage:
    3 stage QPs a step instead of 4, and every step still ends solved by
    both passes' stages."""
    from sm2ith_drake.control.rti_solver import RtiStageSolver

    calls = []
    solve = RtiStageSolver.Solve

    def counted(self, point, **kw):
        calls.append(self.stage.name)
        return solve(self, point, **kw)

    monkeypatch.setattr(RtiStageSolver, "Solve", counted)
    text = (
        "{controller: {rti_iterations: 2, rti_prediction_tolerance: 0, "
        f"rti_early_pass_check: {str(early).lower()}}}}}"
    )
    _, result = _run(
        "crossing_ridgeback_ur10_3h",
        text,
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        duration=1.0,
    )
    solved = [r for r in result.log.records if r.mode == "solved"]
    steps = len(result.log.records)
    assert len(solved) == steps and steps >= 5
    assert {r.passes for r in solved} == {2}
    assert {r.status for r in solved} == {"solved"}
    # Stage QPs per step: (first, [lower,] first, lower). The simulation's
    # last instant also steps the controller, after the log's last record.
    stages = [calls[0], calls[-1]]
    per_step = [stages[0], stages[0], stages[1]]
    if not early:
        per_step.insert(1, stages[1])
    assert stages[0] != stages[1]
    assert len(calls) in (steps * len(per_step), (steps + 1) * len(per_step))
    assert calls == per_step * (len(calls) // len(per_step))


@pytest.mark.parametrize(
    "predictor, safe_text",
    [
        ("react", ""),
        # CVMM's `safe` differs from `paper` by the static guard alone.
        ("cvmm", ", static_guard_steps: 0"),
    ],
)
def test_safety_variants_are_one_controller_without_interactive_prediction(
    predictor, safe_text
):
    """Only SM²ITH's prediction is guarded against people moving on, and
    React's barrier already holds people where they stand: React runs bit for
    bit the same in the `safe` and `paper` variants, and so does CVMM
    without the static guard (a study's variant comparison changes nothing
    else)."""
    crossing = GetDiagramsDir() / "crossing.scenarios.yaml"
    runs = [
        _run(
            "crossing_stretch3_2h",
            f"{{prediction: {{predictor: {predictor}}}, "
            f"safety: {{mode: {mode}{safe_text if mode == 'safe' else ''}}}}}",
            filename=crossing,
            duration=3.0,
        )[1]
        for mode in ("safe", "paper")
    ]
    np.testing.assert_array_equal(
        np.asarray(runs[0].log.states), np.asarray(runs[1].log.states)
    )


@pytest.mark.parametrize("damp_multipliers", [False, True])
def test_proximal_term_damps_the_orca_multipliers_only_if_asked(
    damp_multipliers, monkeypatch
):
    """The RTI's proximal term ½ρ‖z − z̄‖² damps the plan (the robot's
    variables, the people's positions and actions) and, with
    rti_proximal_multipliers (the default), the multipliers of the people's
    relaxed-ORCA QPs: on the QPs PIQP is given (forced here: auto hands these
    small QPs to HPIPM), their Hessian diagonal holds ρ, and nothing without
    it (they have no cost of their own)."""
    from sm2ith_drake.control.piqp_workspace import PiqpWorkspace

    rho = 0.5
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        scenario_name="crossing_ridgeback_ur10_1h",
        scenario_text=f"{{controller: {{qp_solver: piqp, "
        f"rti_proximal_weight: {rho}, "
        f"rti_proximal_multipliers: {str(damp_multipliers).lower()}}}}}",
    )
    diagonals = []
    solve = PiqpWorkspace.Solve

    def Recording(self, p_values, q, *args, **kw):
        rows, cols = self.p_pattern
        diagonal = np.zeros(self.n)
        on = rows == cols
        diagonal[rows[on]] = p_values[on]
        diagonals.append(diagonal)
        return solve(self, p_values, q, *args, **kw)

    monkeypatch.setattr(PiqpWorkspace, "Solve", Recording)
    result = RunSimulation(scenario, duration=0.4)
    assert result.log.records[-1].mode == "solved"
    controller_program = MpcController(
        MakeRobot(scenario),
        scenario.tasks,
        scenario.controller,
        prediction=scenario.prediction,
        safety=scenario.safety,
    ).program
    lam = controller_program.predictor.lam.ravel()
    q = controller_program.layout.q[1:].ravel()
    effort = controller_program.effort_diagonal
    assert diagonals and lam.size
    factor = scenario.controller.rti_later_pass_damping
    assert factor > 1
    seen = set()
    for diagonal in diagonals:
        # A pass the people's predictions asked for is damped by ρ·factor
        # (rti_later_pass_damping), every other by ρ.
        damping = factor if np.isclose(diagonal[lam[0]], rho * factor) else 1.0
        seen.add(damping)
        # The multipliers carry no cost of their own: ρ or nothing.
        expected = rho * damping if damp_multipliers else 0.0
        np.testing.assert_allclose(diagonal[lam], expected, atol=1e-12)
        # The robot's configurations: ρ on top of any task curvature.
        assert np.all(diagonal[q] >= effort[q] + rho * damping - 1e-12)
    assert 1.0 in seen


def test_a_later_pass_is_damped_harder_and_stays_nearer_its_point(monkeypatch):
    """controller.rti_later_pass_damping: a step's first pass damps with
    rti_proximal_weight, a later pass with that times the factor; and on
    one stage QP a heavier damping never ends farther from the
    linearization point (the proximal point's weighted distance does not
    grow with ρ)."""
    from sm2ith_drake.control.rti_solver import RtiStageSolver

    dampings, distances = set(), []
    solve = RtiStageSolver.Solve

    def Recording(self, point, **kw):
        dampings.add(kw["damping"])
        if kw["damping"] == 10.0 and not distances:
            # The same stage QP (the program as it is now), damped 1, 10, 100.
            weights = np.broadcast_to(self.proximal_weight, point.z.shape)
            for damping in (1.0, 10.0, 100.0):
                args = dict(kw, damping=damping, linearizations={})
                result = solve(
                    self, point, **dict(args, lex_bounds=dict(kw["lex_bounds"]))
                )
                assert result.success, result.status
                distances.append(np.sqrt(np.sum(weights * (result.z - point.z) ** 2)))
        return solve(self, point, **kw)

    monkeypatch.setattr(RtiStageSolver, "Solve", Recording)
    _run(
        "crossing_ridgeback_ur10_3h",
        "{controller: {rti_iterations: 2, rti_later_pass_damping: 10}}",
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        duration=1.0,
    )
    assert dampings == {1.0, 10.0}
    assert distances[0] > 0
    assert distances[1] <= distances[0] + 1e-6
    assert distances[2] <= distances[1] + 1e-6
    assert distances[2] < distances[0]


def test_the_qp_iteration_budget_cuts_the_lower_stages_not_the_first():
    """controller.qp_iteration_budget: the first pass's first stage is
    solved whatever the budget; a lower stage gets what is left and, out of
    it, leaves the plan of the stage above ("solved through"); no pass
    starts once the budget is spent. A budget the step does not reach
    changes nothing."""
    text = "{controller: {qp_solver: piqp, rti_iterations: 2}}"
    scenario = LoadScenario(
        filename=CONFLICT, scenario_name="conflict_ee_over_base", scenario_text=text
    )
    robot = MakeRobot(scenario)
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)

    def Solve(budget):
        scenario.controller.qp_iteration_budget = budget
        controller = MpcController(robot, scenario.tasks, scenario.controller)
        targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
        recording = _RecordingStageSolver(controller.solver.stage_solvers[0])
        controller.solver.stage_solvers[0] = recording
        z0 = controller.WarmStart(controller.InitialState(), q0, nu0)
        sol = controller.solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z0)
        return sol, recording.plans

    full, _ = Solve(0)
    assert full.success and full.status == "solved" and full.passes == 2
    unreached, _ = Solve(full.iterations + 1)
    assert unreached.passes == 2
    np.testing.assert_array_equal(unreached.z, full.z)

    # Nothing left after the first stage: its plan, one pass.
    tight, ee_plans = Solve(1)
    assert tight.success and tight.passes == 1
    assert tight.status == (
        "solved through 'ee_position' (stage 'base_position': "
        "QP iteration budget spent)"
    )
    assert len(ee_plans) == 1
    np.testing.assert_array_equal(tight.z, ee_plans[0])
    spent = tight.iterations
    assert spent > 0

    # A few iterations left: the base stage stops at them.
    cut, _ = Solve(spent + 3)
    assert cut.success and cut.passes == 1
    assert cut.status.startswith("solved through 'ee_position'")
    assert cut.iterations == spent + 3

    # Enough for the first pass only: its plan, no second pass.
    scenario.controller.rti_iterations = 1
    first_pass, _ = Solve(0)
    scenario.controller.rti_iterations = 2
    budgeted, _ = Solve(first_pass.iterations)
    assert budgeted.status == "solved" and budgeted.passes == 1
    np.testing.assert_array_equal(budgeted.z, first_pass.z)


@pytest.mark.skipif(not hpipm_library.Available(), reason="HPIPM not built")
def test_the_qp_iteration_budget_counts_piqp_alone():
    """HPIPM's QPs (few people) are capped by its own iter_max: a budget of
    one PIQP iteration leaves a step that HPIPM solves as it was."""
    plans = []
    for budget in (0, 1):
        text = (
            "{controller: {qp_solver: auto, rti_iterations: 2, "
            f"qp_iteration_budget: {budget}}}}}"
        )
        scenario = LoadScenario(
            filename=CONFLICT, scenario_name="conflict_ee_over_base", scenario_text=text
        )
        robot = MakeRobot(scenario)
        controller = MpcController(robot, scenario.tasks, scenario.controller)
        targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
        q0 = np.array(robot.default_q, dtype=float)
        nu0 = np.zeros(robot.num_velocities)
        z0 = controller.WarmStart(controller.InitialState(), q0, nu0)
        sol = controller.solver.Solve(q0=q0, nu0=nu0, targets=targets, z_guess=z0)
        assert sol.status == "solved" and sol.passes == 2
        assert all(s.piqp_iterations == 0 for s in sol.stages)
        plans.append(sol.z)
    np.testing.assert_array_equal(plans[1], plans[0])
