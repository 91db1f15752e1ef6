"""The robot's constraint groups: its dynamics (eq. htmpc_dyn), the task
errors the costs and lexicographic constraints act on, and self-collision
(eq. htmpc_self_collision).
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.groups import BlockPattern, ConstraintGroup, VariableLayout
from sm2ith_drake.control.tasks import Task
from sm2ith_drake.geometry import capsule_distance_and_gradient
from sm2ith_drake.robots.planar_base import VelocityMapPatterns


class DynamicsGroup(ConstraintGroup):
    """Discretized q̇ = G(q)ν, ν̇ = u (eqs. htmpc_dyn, smith_robdyn), as = 0 rows:

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
        base_rows, base_cols = BlockPattern(row_blocks, col_blocks)
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
        # Only the base rows of ∂(Gν)/∂q and G's own nonzeros are ever
        # nonzero in those blocks.
        G, dG = VelocityMapPatterns(robot)
        block = np.concatenate(
            [(np.eye(n, dtype=bool) | dG).ravel(), np.concatenate([G, G], 1).ravel()]
        )
        self.KeepStructuralNonzeros(
            np.concatenate([np.tile(block, N), np.ones(diag_rows.size, dtype=bool)])
        )

    def Eval(self, point):
        robot, dt, N = self._robot, self._dt, self._layout.N
        n, m = self._layout.n, self._layout.m
        q, nu, u = point.q, point.nu, point.u
        G = robot.GStack(q[:N])  # (N, n, m)
        nu_mid = 0.5 * (nu[:-1] + nu[1:])
        dG = robot.dGnu_dqStack(q[:N], nu_mid)  # (N, n, n)
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
        return g, self.Structural(np.concatenate([blocks, diag]))


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
        self.rows, self.cols = BlockPattern(row_blocks, col_blocks)
        self.KeepStructuralNonzeros(np.tile(task.JacobianPattern(layout.n).ravel(), N))

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
        return np.asarray(e).ravel(), self.Structural(np.asarray(J).ravel())


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
            self.rows, self.cols = BlockPattern(row_blocks, col_blocks)
            # A pair's distance moves only with the joints that move one
            # capsule and not the other: a joint that moves both (the base,
            # a shared link) moves them rigidly together.
            masks = robot.capsule_joint_masks
            pair = np.array([masks[a] ^ masks[b] for a, b in self._pairs])  # (P, n)
            pair = np.concatenate([pair, np.ones((P, 1), dtype=bool)], axis=1)
            self.KeepStructuralNonzeros(np.tile(pair.ravel(), N))
        else:
            self.rows = self.cols = np.zeros(0, dtype=int)

    def Eval(self, point):
        if not self._pairs:
            return np.zeros(0), np.zeros(0)
        d, grad = capsule_distance_and_gradient(self._robot, point.kin, self._pairs)
        d, grad = np.asarray(d)[1:], np.asarray(grad)[1:]  # (N, P), (N, P, n)
        jac = np.concatenate([grad, np.ones(grad.shape[:2] + (1,))], axis=2)
        return (d + point.z[self.slack]).ravel(), self.Structural(jac.ravel())


def ModelStep(robot, q, nu, u, time_step: float, nu_lower=None, nu_upper=None):
    """One step of the MPC's discrete model (eq. htmpc_dyn as DynamicsGroup
    writes it): ν' = clip(ν + Δt u) to the velocity limits (or to
    ``nu_lower``, ``nu_upper``), and q' = q + Δt G(q) (ν + ν')/2. Returns
    (q', ν')."""
    lower = robot.nu_lower if nu_lower is None else nu_lower
    upper = robot.nu_upper if nu_upper is None else nu_upper
    nu_next = np.clip(nu + time_step * u, lower, upper)
    return q + 0.5 * time_step * robot.G(q) @ (nu + nu_next), nu_next


def Rollout(robot, q0, nu0, u, time_step: float, nu_bounds=None):
    """Integrates the model from (q0, ν0) with the inputs u (N, m), clipped
    to the acceleration limits (q to the joint limits; ν to the velocity
    limits, or to ``nu_bounds``: (lower, upper), each (N+1, m)): q (N+1, n),
    ν (N+1, m) and the inputs u (N, m) that reproduce them."""
    N = len(u)
    q = np.array(q0, dtype=float)
    nu = np.array(nu0, dtype=float)
    qs = np.empty((N + 1, q.size))
    nus = np.empty((N + 1, nu.size))
    us = np.empty((N, nu.size))
    qs[0], nus[0] = q, nu
    for k in range(N):
        uk = np.clip(u[k], robot.nudot_lower, robot.nudot_upper)
        bounds = (None, None) if nu_bounds is None else (b[k + 1] for b in nu_bounds)
        q, nu = ModelStep(robot, q, nu, uk, time_step, *bounds)
        q = np.clip(q, robot.q_lower, robot.q_upper)
        us[k] = (nu - nus[k]) / time_step
        qs[k + 1], nus[k + 1] = q, nu
    return qs, nus, us
