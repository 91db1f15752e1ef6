"""The arm's joint limits between the knots (control/joint_limits.py)."""

import numpy as np
import pytest

from sm2ith_drake.control.joint_limits import BrakingTrajectory, JointPeakGroup
from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.robots.planar_base import NUM_BASE_POSITIONS, ArmVelocityIndex
from sm2ith_drake.scenario_loader import LoadScenarioAndRobot

WRIST = 5  # joint_wrist_yaw: q index 5, ν index 4 (Stretch 3)


def _Controller(between_knots: bool, solver: str = "rti"):
    """A Stretch 3 whose wrist yaw is limited to ±0.2 rad (as in the
    doorway) and pulled hard toward 1 rad, past its upper limit."""
    text = (
        "{robot: {joint_limits: {joint_wrist_yaw: [-0.2, 0.2]}}, "
        "tasks: [{kind: joint_posture, target: [0.3, 0.2, 1.0, 0.0], "
        "weight: [1, 1, 100000, 1]}], "
        f"controller: {{joint_limits_between_knots: {str(between_knots).lower()}, "
        f"solver: {solver}}}}}"
    )
    scenario, robot = LoadScenarioAndRobot(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name="stretch3_reach",
        scenario_text=text,
    )
    controller = MpcController(robot, scenario.tasks, scenario.controller)
    return controller, robot, scenario.controller.time_step


def _Step(controller, robot, q_wrist, nu_wrist):
    targets = {t.name: np.asarray(t.target, dtype=float) for t in controller.tasks}
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    q0[WRIST] = q_wrist
    nu0[ArmVelocityIndex(robot, WRIST)] = nu_wrist
    return controller.Step(
        controller.InitialState(), time_now=0.0, q0=q0, nu0=nu0, targets=targets
    )


def _Extremes(plan, robot, time_step):
    """Every arm joint's least and greatest position over the plan, between
    the knots included: with the input constant over a step (the model's
    exact motion), a velocity that changes sign within step k turns at
    q_k − ν_k²/(2u_k)."""
    q, nu = np.asarray(plan.q), np.asarray(plan.nu)
    arm_q = np.arange(NUM_BASE_POSITIONS, robot.num_positions)
    arm_nu = ArmVelocityIndex(robot, arm_q)
    lo, hi = q[:, arm_q].min(axis=0), q[:, arm_q].max(axis=0)
    for k in range(len(q) - 1):
        a, b = nu[k, arm_nu], nu[k + 1, arm_nu]
        turns = a * b < 0
        u = (b - a) / time_step
        turn = q[k, arm_q] - np.divide(a * a, 2 * u, where=turns, out=np.zeros_like(a))
        lo = np.where(turns, np.minimum(lo, turn), lo)
        hi = np.where(turns, np.maximum(hi, turn), hi)
    return lo, hi, robot.q_lower[arm_q], robot.q_upper[arm_q]


@pytest.mark.parametrize(
    "q_wrist, nu_wrist", [(0.15, 0.2), (0.1, 0.3), (0.0, 0.5), (-0.19, 0.0)]
)
def test_plan_stays_within_the_limits_between_the_knots(q_wrist, nu_wrist):
    """Pulled past its limit, the wrist's plan reaches the limit and stays
    there: between the knots too. Without the rows the same plan crosses
    the limit between knots in at least one of these states (its velocity
    flips sign each step while its knots sit on the limit)."""
    controller, robot, dt = _Controller(True)
    state = _Step(controller, robot, q_wrist, nu_wrist)
    assert state.record.mode == "solved", state.record.status
    lo, hi, q_lower, q_upper = _Extremes(state.plan, robot, dt)
    assert np.all(lo >= q_lower - 1e-6) and np.all(hi <= q_upper + 1e-6)
    # The wrist does get to its limit: the rows do not hold it short.
    assert np.asarray(state.plan.q)[-1, WRIST] == pytest.approx(0.2, abs=1e-4)


def test_without_the_rows_the_plan_crosses_the_limit_between_knots():
    """The knots alone (eq. htmpc_limits as written) let the wrist swing
    past its limit within a step: what the rows are for."""
    controller, robot, dt = _Controller(False)
    state = _Step(controller, robot, 0.15, 0.2)
    assert state.record.mode == "solved", state.record.status
    _, hi, _, q_upper = _Extremes(state.plan, robot, dt)
    assert hi[WRIST - NUM_BASE_POSITIONS] > q_upper[WRIST - NUM_BASE_POSITIONS] + 5e-3


def test_a_joint_that_cannot_stop_before_its_limit_is_braked():
    """A wrist 6 mrad from its limit at 0.5 rad/s cannot stop before it
    (0.5² / (2 · 2) = 62 mrad): the rows widen to full braking's values, so
    the step is solved, not infeasible, and the plan brakes at full
    deceleration."""
    controller, robot, dt = _Controller(True)
    w = ArmVelocityIndex(robot, WRIST)
    assert 0.5**2 / (2 * robot.nudot_upper[w]) > 0.2 - 0.194
    state = _Step(controller, robot, 0.194, 0.5)
    assert state.record.mode == "solved", state.record.status
    assert state.command_u[w] == pytest.approx(robot.nudot_lower[w])
    group = controller.program.joint_peaks
    assert np.max(group.upper) > 0.2  # widened, to braking's values
    q = np.array(robot.default_q, dtype=float)
    q[WRIST] = 0.194
    nu = np.zeros(robot.num_velocities)
    nu[w] = 0.5
    braking = BrakingTrajectory(robot, q, nu, dt, 10)
    j = WRIST - NUM_BASE_POSITIONS
    assert braking[0][-1, j] > 0.2  # braking passes the limit, then stops
    assert braking[1][-1, j] == 0.0


def test_the_nonlinear_path_reads_the_widened_rows_each_solve():
    """IPOPT's program is built once; the rows' bounds widen with the
    state, so the solver must take them at each solve (NlpStageSolver):
    the wrist too fast to stop is braked there too, not infeasible."""
    controller, robot, _ = _Controller(True, solver="ipopt")
    state = _Step(controller, robot, 0.194, 0.5)
    assert state.record.mode == "solved", state.record.status
    w = ArmVelocityIndex(robot, WRIST)
    assert state.command_u[w] == pytest.approx(robot.nudot_lower[w], rel=1e-4)


def test_group_rows_and_bounds():
    """One row per arm joint with a finite limit and knot 1..N, reading
    q_k and ν_k with coefficients 1 and Δt/2; its bounds the limits, and
    back to them once the state no longer needs braking."""
    controller, robot, dt = _Controller(True)
    layout = controller.program.layout
    group = JointPeakGroup(robot, layout, dt)
    J = robot.num_positions - NUM_BASE_POSITIONS
    assert group.num_rows == layout.N * J
    rng = np.random.default_rng(0)
    z = rng.normal(size=layout.num_variables)
    point = controller.program.MakePoint(z, {})
    g, values = group.Eval(point)
    A = group.DenseJacobian(values, layout.num_variables)
    np.testing.assert_allclose(A @ z, g)  # linear, no offset
    arm_q = np.arange(NUM_BASE_POSITIONS, robot.num_positions)
    expected = (
        z[layout.q[1:]][:, arm_q]
        + 0.5 * dt * z[layout.nu[1:]][:, ArmVelocityIndex(robot, arm_q)]
    )
    np.testing.assert_allclose(g, expected.ravel())
    q0 = np.array(robot.default_q, dtype=float)
    nu0 = np.zeros(robot.num_velocities)
    q0[WRIST], nu0[ArmVelocityIndex(robot, WRIST)] = 0.199, 1.0
    group.SetBraking(BrakingTrajectory(robot, q0, nu0, dt, layout.N))
    assert np.max(group.upper) > 0.2
    group.SetBraking(
        BrakingTrajectory(robot, q0, np.zeros(robot.num_velocities), dt, layout.N)
    )
    np.testing.assert_array_equal(group.upper, np.tile(robot.q_upper[arm_q], 10))
    np.testing.assert_array_equal(group.lower, np.tile(robot.q_lower[arm_q], 10))


def test_far_rows_are_those_well_inside_both_limits():
    """FarRows (PIQP may leave a row out and check it at its solution)
    marks exactly the rows more than the distance inside both bounds."""
    controller, robot, dt = _Controller(True)
    group = controller.program.joint_peaks
    q = np.tile(np.array(robot.default_q, dtype=float), (11, 1))
    q[:, WRIST] = 0.19  # 1 cm inside its upper limit
    layout = controller.program.layout
    z = np.zeros(layout.num_variables)
    z[layout.q] = q
    point = controller.program.MakePoint(z, {})
    g, _ = group.Eval(point)
    far = group.FarRows(point, 0.05)
    inside = np.minimum(g - group.lower, group.upper - g)
    np.testing.assert_array_equal(far, inside > 0.05)
    per_knot = group.num_rows // layout.N  # lift, arm, wrist yaw, wrist pitch
    wrist_rows = np.arange(layout.N) * per_knot + 2
    assert not np.any(far[wrist_rows]) and np.any(far)
