"""One MPC program: variables, constraint groups and least-squares costs.

The program is described once, as groups of vector-valued functions with a
fixed sparsity pattern: each group evaluates its values g(z̄) and the nonzeros
of ∂g/∂z at a point z̄. Two solvers consume that description
(:mod:`sm2ith_drake.control.htmpc`): the real-time iteration, which linearizes
every group at the warm start and solves sparse QPs in a persistent PIQP
workspace, and the nonlinear path, which hands the same functions with their
analytic Jacobians to SNOPT or IPOPT through a MathematicalProgram.

Variables (eq. htmpc): q_0..q_N (configuration), ν_0..ν_N (pseudo-velocities)
and u_0..u_{N-1} = ν̇ (input). Predictors of human motion append their own
variables and groups through :meth:`VariableLayout.AddVariables` and
:class:`ConstraintGroup`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sm2ith_drake.control.tasks import Task
from sm2ith_drake.geometry import capsule_distance_and_gradient

# Exact-penalty weights of constraint slacks (large against task costs of
# order 1 per metre of error).
SLACK_LINEAR_WEIGHT = 1e3
SLACK_QUADRATIC_WEIGHT = 1e4
CBF_SLACK_LINEAR_WEIGHT = 1e4


class VariableLayout:
    """Indices of the decision variables in the flat vector z."""

    def __init__(self, *, num_positions: int, num_velocities: int, horizon: int):
        n, m, N = num_positions, num_velocities, horizon
        self.n, self.m, self.N = n, m, N
        self.num_variables = 0
        self.q = self.AddVariables("q", (N + 1, n))
        self.nu = self.AddVariables("nu", (N + 1, m))
        self.u = self.AddVariables("u", (N, m))
        self.robot_variables = self.num_variables

    def AddVariables(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """Appends variables to z; returns their indices with the given shape."""
        count = int(np.prod(shape))
        idx = np.arange(self.num_variables, self.num_variables + count).reshape(shape)
        self.num_variables += count
        return idx

    def Split(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return z[self.q], z[self.nu], z[self.u]


@dataclass
class LinearizationPoint:
    """A point z̄ with everything the groups need, computed once per point."""

    z: np.ndarray
    q: np.ndarray  # (N+1, n)
    nu: np.ndarray  # (N+1, m)
    u: np.ndarray  # (N, m)
    kin: object  # robot.CalcKinematics(q)
    # Task targets by task name: (s,) or per step (N+1, s).
    targets: dict = field(default_factory=dict)
    # Memo of task evaluations (name → (e, J)), filled lazily.
    task_cache: dict = field(default_factory=dict)


class ConstraintGroup:
    """lower ≤ g(z) ≤ upper with a fixed Jacobian sparsity pattern.

    Subclasses set ``num_rows``, ``rows`` and ``cols`` (the nonzeros of ∂g/∂z,
    local row index and global column index) and implement :meth:`Eval`.
    """

    name = "group"
    num_rows: int
    rows: np.ndarray
    cols: np.ndarray

    def Eval(self, point: LinearizationPoint) -> tuple[np.ndarray, np.ndarray]:
        """Returns g(z̄) (num_rows,) and the Jacobian nonzeros (nnz,)."""
        raise NotImplementedError

    def DenseJacobian(self, values: np.ndarray, num_variables: int) -> np.ndarray:
        J = np.zeros((self.num_rows, num_variables))
        np.add.at(J, (self.rows, self.cols), values)
        return J


def _BlockPattern(row_blocks, col_blocks):
    """Pattern of dense blocks: row_blocks[i] × col_blocks[i] (index arrays)."""
    rows, cols = [], []
    for r, c in zip(row_blocks, col_blocks, strict=True):
        rr, cc = np.meshgrid(r, c, indexing="ij")
        rows.append(rr.ravel())
        cols.append(cc.ravel())
    return np.concatenate(rows), np.concatenate(cols)


class DynamicsGroup(ConstraintGroup):
    """Discretized q̇ = G(q)ν, ν̇ = u (eq. htmpc_dyn), as = 0 rows:

        ν_{k+1} − ν_k − Δt u_k = 0,
        q_{k+1} − q_k − Δt G(q_k) (ν_k + ν_{k+1}) / 2 = 0.

    With u constant over a step this is the exact motion of the joints (and
    of the base up to the heading change within the step), so the plan
    matches what the robot does; and q_1 depends on u_0, so a joint moving
    toward its limit can still be stopped by the first input.
    """

    name = "dynamics"

    def __init__(self, robot, layout: VariableLayout, time_step: float):
        self._robot = robot
        self._layout = layout
        self._dt = time_step
        n, m, N = layout.n, layout.m, layout.N
        self.num_rows = N * (n + m)
        # Per step k the q rows depend on q_k (all n: identity + the θ column
        # of ∂(Gν)/∂q, kept dense for a fixed pattern), q_{k+1} (diagonal),
        # ν_k and ν_{k+1} (all m each); the ν rows on ν_k, ν_{k+1}, u_k.
        row_blocks, col_blocks = [], []
        self._q_rows = np.arange(N)[:, None] * (n + m) + np.arange(n)[None, :]
        self._nu_rows = self._q_rows[:, :1] + n + np.arange(m)[None, :]
        for k in range(N):
            qr = self._q_rows[k]
            row_blocks += [qr, qr]
            col_blocks += [
                layout.q[k],
                np.concatenate([layout.nu[k], layout.nu[k + 1]]),
            ]
        base_rows, base_cols = _BlockPattern(row_blocks, col_blocks)
        diag_rows = np.concatenate(
            [
                self._q_rows.ravel(),
                self._nu_rows.ravel(),
                self._nu_rows.ravel(),
                self._nu_rows.ravel(),
            ]
        )
        diag_cols = np.concatenate(
            [
                layout.q[1:].ravel(),
                layout.nu[1:].ravel(),
                layout.nu[:-1].ravel(),
                layout.u.ravel(),
            ]
        )
        self.rows = np.concatenate([base_rows, diag_rows])
        self.cols = np.concatenate([base_cols, diag_cols])

    def Eval(self, point):
        robot, dt, N = self._robot, self._dt, self._layout.N
        n, m = self._layout.n, self._layout.m
        q, nu, u = point.q, point.nu, point.u
        G = np.stack([robot.G(q[k]) for k in range(N)])  # (N, n, m)
        nu_mid = 0.5 * (nu[:-1] + nu[1:])
        dG = np.stack([robot.dGnu_dq(q[k], nu_mid[k]) for k in range(N)])  # (N, n, n)
        qdot = np.einsum("knm,km->kn", G, nu_mid)
        g = np.empty(self.num_rows)
        g[self._q_rows.ravel()] = (q[1:] - q[:-1] - dt * qdot).ravel()
        g[self._nu_rows.ravel()] = (nu[1:] - nu[:-1] - dt * u).ravel()
        dq_k = -np.eye(n)[None] - dt * dG  # (N, n, n)
        half = -0.5 * dt * G  # (N, n, m), the same for ν_k and ν_{k+1}
        dnu = np.concatenate([half, half], axis=2)  # (N, n, 2m)
        blocks = np.concatenate(
            [dq_k.reshape(N, n * n), dnu.reshape(N, 2 * n * m)], axis=1
        ).ravel()
        diag = np.concatenate(
            [np.ones(N * n), np.ones(N * m), -np.ones(N * m), -dt * np.ones(N * m)]
        )
        return g, np.concatenate([blocks, diag])


class TaskErrorGroup(ConstraintGroup):
    """The errors e_k, k = 1..N, of one task (rows k-major, then component)."""

    def __init__(self, task: Task, layout: VariableLayout):
        self.task = task
        self.name = f"task:{task.name}"
        N, s = layout.N, task.dim
        self._N = N
        self.num_rows = N * s
        row_blocks = [k * s + np.arange(s) for k in range(N)]
        col_blocks = [layout.q[k + 1] for k in range(N)]
        self.rows, self.cols = _BlockPattern(row_blocks, col_blocks)

    def ErrorAndJacobian(self, point):
        cached = point.task_cache.get(self.task.name)
        if cached is None:
            target = np.asarray(point.targets[self.task.name], dtype=float)
            if target.ndim == 2:
                target = target[1:]
            cached = self.task.CalcErrorAndJacobian(
                point.q[1:], _KinSlice(point.kin), target
            )
            point.task_cache[self.task.name] = cached
        return cached

    def Eval(self, point):
        e, J = self.ErrorAndJacobian(point)
        return np.asarray(e).ravel(), np.asarray(J).ravel()


class _KinSlice:
    """The kinematics of steps 1..N (tasks skip the fixed step 0)."""

    def __init__(self, kin):
        self._kin = kin

    def __getattr__(self, name):
        return getattr(self._kin, name)[1:]


class SelfCollisionGroup(ConstraintGroup):
    """sd(q_k) + σ_k ≥ d_sc for every self-collision capsule pair, k = 1..N
    (eq. htmpc_self_collision), with slacks σ ≥ 0 under an exact (L1 plus
    quadratic) penalty.

    The slacks are zero whenever the hard constraint can be met; they keep
    the program feasible when the measured state is already inside the
    margin (a linearization error, a disturbance), so the controller steers
    back out instead of failing.
    """

    name = "self_collision"

    def __init__(self, robot, layout: VariableLayout):
        self._robot = robot
        self._pairs = list(robot.self_collision_pairs)
        N, P = layout.N, len(self._pairs)
        self.num_rows = N * P
        self.slack = layout.AddVariables("self_collision_slack", (N, P))
        row_blocks = [k * P + np.array([p]) for k in range(N) for p in range(P)]
        col_blocks = [
            np.concatenate([layout.q[k + 1], [self.slack[k, p]]])
            for k in range(N)
            for p in range(P)
        ]
        if P:
            self.rows, self.cols = _BlockPattern(row_blocks, col_blocks)
        else:
            self.rows = self.cols = np.zeros(0, dtype=int)

    def Eval(self, point):
        if not self._pairs:
            return np.zeros(0), np.zeros(0)
        d, grad = capsule_distance_and_gradient(self._robot, point.kin, self._pairs)
        d, grad = np.asarray(d)[1:], np.asarray(grad)[1:]  # (N, P), (N, P, n)
        jac = np.concatenate([grad, np.ones(grad.shape[:2] + (1,))], axis=2)
        return (d + point.z[self.slack]).ravel(), jac.ravel()


class MpcProgram:
    """The groups and bounds shared by every stage of the hierarchy."""

    def __init__(
        self,
        *,
        robot,
        tasks: list[Task],
        horizon: int,
        time_step: float,
        self_collision_distance: float,
        effort_weight_nu: float,
        effort_weight_u: float,
        predictor=None,
        safety=None,
        obstacle_segments=None,
    ):
        """``predictor`` (humans/predictors.py) adds the human variables and
        its constraints; with humans or ``obstacle_segments`` (S, 2, 2), the
        DT-CBF constraints of ``safety`` (a SafetyConfig) are added."""
        self.robot = robot
        self.tasks = list(tasks)
        self.time_step = time_step
        self.layout = VariableLayout(
            num_positions=robot.num_positions,
            num_velocities=robot.num_velocities,
            horizon=horizon,
        )
        L = self.layout
        self.dynamics = DynamicsGroup(robot, L, time_step)
        self.self_collision = SelfCollisionGroup(robot, L)
        self.self_collision_distance = self_collision_distance
        self.task_groups = {t.name: TaskErrorGroup(t, L) for t in self.tasks}
        # Extra groups from the human predictor and the DT-CBF safety
        # constraints: (group, lower, upper).
        self.extra_constraints: list[
            tuple[ConstraintGroup, np.ndarray, np.ndarray]
        ] = []
        self.predictor = predictor
        self.cbf = None
        segments = (
            np.zeros((0, 2, 2))
            if obstacle_segments is None
            else np.asarray(obstacle_segments, dtype=float).reshape(-1, 2, 2)
        )
        if predictor is not None:
            predictor.AddVariables(L)
            self.extra_constraints += predictor.ConstraintGroups(self)
        if (predictor is not None and predictor.H) or len(segments):
            from sm2ith_drake.control.cbf import DtCbfGroup
            from sm2ith_drake.scenario import SafetyConfig

            safety = safety or SafetyConfig()
            positions = (
                predictor.p
                if predictor is not None
                else np.zeros((L.N + 1, 0, 2), dtype=int)
            )
            self.cbf = DtCbfGroup(
                robot,
                L,
                positions,
                gamma=safety.gamma,
                human_radius=safety.human_radius,
                human_margin=safety.human_margin,
                obstacle_segments=segments,
                obstacle_margin=safety.obstacle_margin,
                guard_steps=safety.guard_steps if predictor is not None else 0,
            )
            nr = self.cbf.num_rows
            self.extra_constraints.append((self.cbf, np.zeros(nr), np.full(nr, np.inf)))
        # Effort J_eff = ½ Σ w_ν‖ν_k‖² (k=1..N) + w_u‖u_k‖² (k=0..N-1).
        self.effort_diagonal = np.zeros(L.num_variables)
        self.effort_diagonal[L.nu[1:].ravel()] = effort_weight_nu
        self.effort_diagonal[L.u.ravel()] = effort_weight_u
        # Penalty on the self-collision slacks: ½ w_q σ² + w_l σ.
        self.linear_cost = np.zeros(L.num_variables)
        self.effort_diagonal[self.self_collision.slack.ravel()] = SLACK_QUADRATIC_WEIGHT
        self.linear_cost[self.self_collision.slack.ravel()] = SLACK_LINEAR_WEIGHT
        # Variable bounds (eq. htmpc_limits); q_0, ν_0 pinned each step.
        lower = np.full(L.num_variables, -np.inf)
        upper = np.full(L.num_variables, np.inf)
        lower[L.q] = robot.q_lower
        upper[L.q] = robot.q_upper
        lower[L.nu] = robot.nu_lower
        upper[L.nu] = robot.nu_upper
        lower[L.u] = robot.nudot_lower
        upper[L.u] = robot.nudot_upper
        lower[self.self_collision.slack.ravel()] = 0.0
        if self.cbf is not None:
            self.effort_diagonal[self.cbf.slack] = SLACK_QUADRATIC_WEIGHT
            self.linear_cost[self.cbf.slack] = CBF_SLACK_LINEAR_WEIGHT
            lower[self.cbf.slack] = 0.0
        self.variable_lower = lower
        self.variable_upper = upper

    def PatternKey(self) -> bytes:
        """Identifies the groups' current Jacobian sparsity patterns (they
        change only with the predictor's neighbour sets)."""
        return getattr(self.predictor, "pattern_key", b"")

    def VariableBounds(self, q0: np.ndarray, nu0: np.ndarray):
        """Variable bounds with the initial condition (eq. htmpc_init) pinned."""
        L = self.layout
        lower = self.variable_lower.copy()
        upper = self.variable_upper.copy()
        lower[L.q[0]] = upper[L.q[0]] = q0
        # The measured ν may sit marginally outside its limits; pinning it is
        # still consistent because only ν_1.. are bounded by the limits.
        lower[L.nu[0]] = upper[L.nu[0]] = nu0
        self._WidenForBraking(lower, upper, q0, nu0)
        if self.predictor is not None:
            self.predictor.ApplyBounds(lower, upper)
            if self.cbf is not None and self.cbf.num_guard:
                self.cbf.SetGuard(self.predictor.p0, self.predictor.v0, self.time_step)
        return lower, upper

    def _WidenForBraking(self, lower, upper, q0, nu0) -> None:
        """Keeps the problem feasible when an arm joint moves toward a limit
        too fast to stop before it: at every knot where full braking would
        still pass the limit, the bound becomes the braking trajectory's
        position, held for the rest of the horizon once braking has stopped
        the joint (the plan then brakes that joint; the robot itself stops
        at the limit). Without this the QP is infeasible and the step falls
        back, although braking is exactly what the plan should do."""
        L, dt, robot = self.layout, self.time_step, self.robot
        n, m = robot.num_positions, robot.num_velocities
        arm_q = np.arange(3, n)
        arm_nu = arm_q + (m - n)
        v = np.asarray(nu0, dtype=float)[arm_nu].copy()
        if not np.all(np.isfinite(v)) or not np.any(v):
            return
        a = np.minimum(-robot.nudot_lower[arm_nu], robot.nudot_upper[arm_nu])
        q = np.asarray(q0, dtype=float)[arm_q].copy()
        for k in range(1, L.N + 1):
            v_next = np.sign(v) * np.maximum(np.abs(v) - a * dt, 0.0)
            q = q + 0.5 * dt * (v + v_next)
            v = v_next
            cols = np.asarray(L.q[k])[arm_q]
            # Past the limit the joint may stay where braking stopped it.
            upper[cols] = np.maximum(upper[cols], q)
            lower[cols] = np.minimum(lower[cols], q)

    def MakePoint(self, z: np.ndarray, targets: dict) -> LinearizationPoint:
        q, nu, u = self.layout.Split(z)
        return LinearizationPoint(
            z=z, q=q, nu=nu, u=u, kin=self.robot.CalcKinematics(q), targets=targets
        )

    def Rollout(self, q0: np.ndarray, nu0: np.ndarray, u: np.ndarray) -> np.ndarray:
        """z from integrating the model with inputs u (ν clipped to limits)."""
        L, dt, robot = self.layout, self.time_step, self.robot
        z = np.zeros(L.num_variables)
        q, nu = np.array(q0, dtype=float), np.array(nu0, dtype=float)
        z[L.q[0]], z[L.nu[0]] = q, nu
        for k in range(L.N):
            uk = np.clip(u[k], robot.nudot_lower, robot.nudot_upper)
            nu_next = np.clip(nu + dt * uk, robot.nu_lower, robot.nu_upper)
            q = np.clip(
                q + 0.5 * dt * robot.G(q) @ (nu + nu_next), robot.q_lower, robot.q_upper
            )
            nu = nu_next
            uk = (nu - z[L.nu[k]]) / dt
            z[L.u[k]], z[L.q[k + 1]], z[L.nu[k + 1]] = uk, q, nu
        return z

    def ConstraintGroups(self) -> list[tuple[ConstraintGroup, np.ndarray, np.ndarray]]:
        """The (group, lower, upper) rows every stage shares."""
        out = [
            (
                self.dynamics,
                np.zeros(self.dynamics.num_rows),
                np.zeros(self.dynamics.num_rows),
            ),
        ]
        if self.self_collision.num_rows:
            nr = self.self_collision.num_rows
            out.append(
                (
                    self.self_collision,
                    np.full(nr, self.self_collision_distance),
                    np.full(nr, np.inf),
                )
            )
        return out + list(self.extra_constraints)
