"""The arm's joint limits (eq. htmpc_limits) between the knots, and the
bounds that keep them feasible when a joint cannot stop before a limit.

The variable bounds hold q_k within the limits at the knots only. With the
input constant over a step (DynamicsGroup), a joint whose velocity reverses
within step k turns at t* = ν_k/|u_k| ≤ Δt, at q_k + ν_k t*/2: beyond both
knots. :class:`JointPeakGroup` bounds that peak by

    q_lower ≤ q_k + (Δt/2) ν_k ≤ q_upper,   k = 1..N,

which holds it within the limits (a joint whose velocity keeps its sign
has its extremes at the knots). Knot 0 is the measured state: a plan that
met the row at its knot 1 starts the next step within it, so step 0 stays
within the limits as well.

Why (README, Doorway): the simulated robot, like a joint against its hard
stop, loses its velocity at a limit at once; the plan's reversing input
then carried the joint back at twice the planned rate. Among the Stretch
3's doorway runs half the samples in which the robot closed in on a person
it touched came within 0.25 s after an arm joint stopped at a limit.
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.groups import ConstraintGroup, VariableLayout
from sm2ith_drake.robots.planar_base import NUM_BASE_POSITIONS, ArmVelocityIndex


def BrakingTrajectory(robot, q0, nu0, time_step: float, horizon: int):
    """The arm joints braking as hard as their acceleration limits allow
    from (q0, ν0): q (N+1, J) and ν (N+1, J) at the knots (J: every arm
    joint), or None where no joint moves (or the state is not finite).
    Computed once a step for WidenForBraking and JointPeakGroup."""
    arm_q = np.arange(NUM_BASE_POSITIONS, robot.num_positions)
    arm_nu = ArmVelocityIndex(robot, arm_q)
    v = np.asarray(nu0, dtype=float)[arm_nu].copy()
    if not np.all(np.isfinite(v)) or not np.any(v):
        return None
    a = np.minimum(-robot.nudot_lower[arm_nu], robot.nudot_upper[arm_nu])
    q = np.asarray(q0, dtype=float)[arm_q].copy()
    qs, vs = [q], [v]
    for _ in range(horizon):
        v_next = np.sign(v) * np.maximum(np.abs(v) - a * time_step, 0.0)
        q = q + 0.5 * time_step * (v + v_next)
        v = v_next
        qs.append(q)
        vs.append(v)
    return np.array(qs), np.array(vs)


def WidenForBraking(layout: VariableLayout, braking, lower, upper):
    """Keeps the problem feasible when an arm joint moves toward a limit
    too fast to stop before it: at every knot where full braking (the
    BrakingTrajectory ``braking``) would still pass the limit, the bound
    (``lower``, ``upper``: the variable bounds, changed in place) becomes
    the braking trajectory's position, held for the rest of the horizon
    once braking has stopped the joint (the plan then brakes that joint;
    the robot itself stops at the limit). Without this the QP is infeasible
    and the step falls back, although braking is exactly what the plan
    should do."""
    if braking is None:
        return
    q = braking[0]
    arm_q = np.arange(NUM_BASE_POSITIONS, layout.n)
    cols = np.asarray(layout.q)[1:, arm_q]  # (N, J)
    # Past the limit the joint may stay where braking stopped it.
    upper[cols] = np.maximum(upper[cols], q[1:])
    lower[cols] = np.minimum(lower[cols], q[1:])


class JointPeakGroup(ConstraintGroup):
    """q_lower ≤ q_k + (Δt/2) ν_k ≤ q_upper for every arm joint with a
    finite limit, k = 1..N (rows k-major, then joint; module doc).

    Its bounds, :attr:`lower` and :attr:`upper`, are the arrays the program
    hands to the stage solvers; :meth:`SetBraking` widens them in place each
    step as WidenForBraking widens the variable bounds, to the braking
    trajectory's own values where it passes a limit (a pure function of the
    measured state: nothing lasts between steps)."""

    name = "joint_peaks"
    # FarRows' threshold: controller.lazy_barrier_distance (0.5), in rad or
    # m here; a joint that far from both limits is left out of PIQP's QPs
    # and checked at the solution.

    def __init__(self, robot, layout: VariableLayout, time_step: float):
        self._dt = time_step
        N = layout.N
        arm_q = np.arange(NUM_BASE_POSITIONS, robot.num_positions)
        limited = np.isfinite(robot.q_lower[arm_q]) | np.isfinite(robot.q_upper[arm_q])
        self._limited = np.nonzero(limited)[0]  # of the arm's joints
        self._arm_q = arm_q[limited]
        self._arm_nu = ArmVelocityIndex(robot, self._arm_q)
        J = self._arm_q.size
        self.num_rows = N * J
        q_cols = np.asarray(layout.q)[1:, self._arm_q]  # (N, J)
        nu_cols = np.asarray(layout.nu)[1:, self._arm_nu]
        self.rows = np.repeat(np.arange(self.num_rows), 2)
        self.cols = np.stack([q_cols.ravel(), nu_cols.ravel()], axis=1).ravel()
        self._values = np.tile([1.0, 0.5 * time_step], self.num_rows)
        self._base_lower = np.tile(robot.q_lower[self._arm_q], N)
        self._base_upper = np.tile(robot.q_upper[self._arm_q], N)
        self.lower = self._base_lower.copy()
        self.upper = self._base_upper.copy()

    def Eval(self, point):
        g = point.q[1:, self._arm_q] + 0.5 * self._dt * point.nu[1:, self._arm_nu]
        return g.ravel(), self._values

    def FarRows(self, point, distance):
        """Rows more than ``distance`` (rad or m) inside both bounds at
        ``point``: a QP solver may leave them out and check them at its
        solution (ConstraintGroup.FarRows)."""
        g, _ = self.Eval(point)
        far = (g - self.lower > distance) & (self.upper - g > distance)
        return far if np.any(far) else None

    def SetBraking(self, braking) -> None:
        """The bounds for the measured state, given its BrakingTrajectory
        ``braking`` (class doc)."""
        self.lower[:] = self._base_lower
        self.upper[:] = self._base_upper
        if braking is None:
            return
        q, v = (b[1:, self._limited] for b in braking)
        peak = (q + 0.5 * self._dt * v).ravel()
        np.maximum(self.upper, peak, out=self.upper)
        np.minimum(self.lower, peak, out=self.lower)
