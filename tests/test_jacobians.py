"""Every constraint group's analytic Jacobian against central differences
(issue 11, item 6): the robot dynamics, self-collision, the ORCA-KKT
equalities and inequalities, the DT-CBF (with its guard rows) and every
kind of task error, on both robots, with and without people."""

import numpy as np
import pytest

from sm2ith_drake.control.mpc_controller import MpcController
from sm2ith_drake.control.tasks import FACE_POINT_RADIUS, MakeTask
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import (
    ControllerConfig,
    ObstacleConfig,
    PredictionConfig,
    SafetyConfig,
    TaskConfig,
)

# A short horizon keeps the differencing affordable; every group's rows
# are the same per step, so three steps exercise all of them (the DT-CBF's
# guard rows cover steps 0 and 1).
HORIZON = 3
STEP = 1e-6
# Tolerances (absolute, plus relative to the column's largest entry). The
# KKT groups take the ORCA lines' derivatives by central differences
# themselves (orca_kkt.py), so they match to that accuracy only.
TOLERANCES = {"orca_kkt_equalities": 2e-5, "orca_kkt_inequalities": 2e-5}
DEFAULT_TOLERANCE = 2e-6


def _Tasks(robot):
    """One task of every kind (targets away from the current state)."""
    arm = robot.num_positions - 3
    return [
        TaskConfig(kind="ee_position", target=[1.0, 0.3, 0.8]),
        TaskConfig(kind="base_position", target=[2.0, -0.5]),
        TaskConfig(
            kind="base_position", name="base_ahead", target=[2.0, -0.5], offset=0.15
        ),
        TaskConfig(kind="base_pose", target=[2.0, -0.5, 0.7]),
        TaskConfig(kind="ee_position_in_base", target=[0.5, 0.1, 0.9]),
        TaskConfig(kind="joint_posture", target=[0.2] * arm),
        TaskConfig(kind="face_point", target=[2.0, -0.5]),
        TaskConfig(kind="face_point", name="face_near", target=[0.1, 0.15]),
    ]


def _Point(robot_name, with_people, kkt_steps=0):
    robot = MobileManipulator(robot_name)
    tasks = _Tasks(robot)
    wall = ObstacleConfig(vertices=[[1.5, -0.8], [4.5, -0.8]])
    prediction = None
    if with_people:
        # Three people with one neighbour each: the capped neighbour sets
        # (K < H − 1) with their exact derivatives.
        prediction = PredictionConfig(
            predictor="orca_kkt",
            max_humans=3,
            max_neighbors=1,
            neighbor_derivatives=True,
            max_extra_humans=2,  # the two farther people: barrier rows
            kkt_steps=kkt_steps,
        )
    c = MpcController(
        robot,
        tasks,
        ControllerConfig(horizon=HORIZON),
        prediction=prediction,
        safety=SafetyConfig(guard_steps=2),
        obstacles=[wall],
    )
    rng = np.random.default_rng(7)
    q0 = robot.default_q.copy()
    q0[3:] += rng.uniform(-0.3, 0.3, robot.num_positions - 3)
    q0 = np.clip(q0, robot.q_lower + 0.05, robot.q_upper - 0.05)
    nu0 = 0.2 * robot.nu_upper * rng.uniform(-1, 1, robot.num_velocities)
    if with_people:
        model = c.human_predictor
        prediction, _ = model.Predict(
            model.InitialState(),
            estimate=HumanEstimate(
                ids=[0, 1, 2, 3, 4],
                positions=[[3.0, 0.1], [3.0, 0.9], [3.0, 1.7], [4.0, -0.3], [4.5, 1.2]],
                velocities=[[-1.0, 0.0]] * 3 + [[-0.8, 0.2], [-0.5, -0.5]],
            ),
            q0=q0,
            nu0=nu0,
            warm_start_inputs=c.WarmStartInputs(c.InitialState()),
        )
        assert sorted(prediction.extra_ids.tolist()) == [3, 4]
        c.predictor.SetPrediction(prediction)
    c.program.VariableBounds(q0, nu0)  # sets the DT-CBF's guard
    z = c.WarmStart(c.InitialState(), q0, nu0)
    z = z + rng.normal(scale=1e-2, size=z.size)
    targets = {t.name: np.asarray(t.target, dtype=float) for t in c.tasks}
    return c, z, targets


def _Groups(c):
    groups = [group for group, _, _ in c.program.ConstraintGroups()]
    return groups + list(c.program.task_groups.values())


@pytest.mark.parametrize(
    "with_people, kkt_steps",
    [(False, 0), (True, 0), (True, HORIZON - 1)],
    ids=["alone", "people", "people_held_last_step"],
)
@pytest.mark.parametrize("robot_name", ["ridgeback_ur10", "stretch3"])
def test_every_group_jacobian_matches_central_differences(
    robot_name, with_people, kkt_steps
):
    """Every group's Jacobian against central differences of its values;
    with ``kkt_steps`` < N the last step holds the action of the one before
    (rows a_k − a_{k−1}) instead of its KKT rows."""
    c, z, targets = _Point(robot_name, with_people, kkt_steps)
    program = c.program
    groups = _Groups(c)
    names = {g.name for g in groups}
    expected = {"dynamics", "self_collision", "joint_peaks", "dt_cbf"} | {
        f"task:{t.name}" for t in c.tasks
    }
    if with_people:
        expected |= {"orca_kkt_equalities", "orca_kkt_inequalities"}
        assert program.cbf.num_guard > 0
    assert names == expected
    point = program.MakePoint(z, targets)
    analytic = {g.name: g.DenseJacobian(g.Eval(point)[1], z.size) for g in groups}
    columns = {g.name: np.unique(g.cols) for g in groups}
    fd = {g.name: np.zeros((g.num_rows, z.size)) for g in groups}
    # One pair of points per column that any group's pattern has (all of z
    # here), every group evaluated at it: a dependence on a column that a
    # group's pattern leaves out is caught too.
    differenced = np.unique(np.concatenate(list(columns.values())))
    # Past kkt_steps no row reads the multipliers (they are pinned to 0).
    unused = c.predictor.lam[kkt_steps:].ravel() if kkt_steps else []
    assert np.setdiff1d(np.arange(z.size), differenced).tolist() == sorted(unused)
    for i in differenced:
        zp, zm = z.copy(), z.copy()
        zp[i] += STEP
        zm[i] -= STEP
        plus = program.MakePoint(zp, targets)
        minus = program.MakePoint(zm, targets)
        # Evaluated group by group at one point, then the other (the KKT
        # groups share one evaluation per point).
        up = [g.Eval(plus)[0] for g in groups]
        down = [g.Eval(minus)[0] for g in groups]
        for g, gp, gm in zip(groups, up, down, strict=True):
            fd[g.name][:, i] = (gp - gm) / (2 * STEP)
    for g in groups:
        J, F, cols = analytic[g.name], fd[g.name], columns[g.name]
        tol = TOLERANCES.get(g.name, DEFAULT_TOLERANCE)
        assert np.max(np.abs(F)) > 1e-3, f"{g.name}: the differences are all zero"
        # Outside the declared pattern the function does not depend on z.
        in_pattern = np.zeros_like(F, dtype=bool)
        in_pattern[g.rows, g.cols] = True
        outside = np.abs(F[~in_pattern])
        assert np.max(outside) < tol, (
            f"{g.name}: depends on z outside its pattern, e.g. column "
            f"{np.nonzero(np.abs(F) * ~in_pattern >= tol)[1][0]}"
        )
        scale = np.maximum(1.0, np.max(np.abs(F[:, cols]), axis=0))
        error = np.abs(J[:, cols] - F[:, cols]) / scale
        worst = np.unravel_index(np.argmax(error), error.shape)
        assert error[worst] < tol, (
            f"{g.name}: row {worst[0]}, column {cols[worst[1]]}: analytic "
            f"{J[worst[0], cols[worst[1]]]:.3e}, differences "
            f"{F[worst[0], cols[worst[1]]]:.3e}"
        )


def test_face_point_error_against_hand_values():
    """face_point: 0 facing the point, the signed angle off it (π/2 turned
    left of it), and faded out linearly within FACE_POINT_RADIUS of it."""
    task = MakeTask(TaskConfig(kind="face_point", target=[2.0, 1.0]), 3)
    qs = np.array(
        [
            [0.0, 1.0, 0.0],  # facing it, 2 m away
            [0.0, 1.0, np.pi / 2],  # turned left of it
            [2.0, 0.0, 0.0],  # 1 m straight below it, facing +x
            [2.0, 1.0 - FACE_POINT_RADIUS / 2, np.pi],  # half the radius below
        ]
    )
    e, _ = task.CalcErrorAndJacobian(qs, None, task.target)
    np.testing.assert_allclose(
        e[:, 0], [0.0, np.pi / 2, -np.pi / 2, 0.5 * np.pi / 2], atol=1e-12
    )
