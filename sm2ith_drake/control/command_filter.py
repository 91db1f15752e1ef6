"""A last check on the command before it goes out (``safety.command_filter``,
`safe` variant only): the robot's own motion over the next control period
obeys the DT-CBF against every person standing where measured.

The DT-CBF rows of the MPC carry slack (an exact penalty), so when the
barriers cannot all hold, e.g. a person walking at the robot in a door with
another person beside it, the plan trades one person's margin for another's
and may drive the robot into someone within reach. This filter holds the
robot's own part: with h = d − reach (d from the robot's nearest body to a
person's centre, reach = human radius + margin), the motion under the
command may lower h by at most γ·s·max(h₀, 0) by the share s of the period
(none inside the margin), checked at four instants within the period
(a swinging link can close in and open again within one period). If the
plan's command breaks that, the closest command that keeps it, to first
order, replaces it (a small QP; soft where the limits allow no such command,
e.g. a base already turning toward someone: the least violation is taken),
checked on the nonlinear distances. Only the robot's motion is constrained:
people may still walk into a robot that holds its ground.
"""

from __future__ import annotations

import numpy as np
import piqp

from sm2ith_drake.control.robot_groups import ModelStep
from sm2ith_drake.humans.robot_view import HumanDistances

# Violations below this (m) are not corrected.
CLOSING_TOLERANCE = 1e-4
# People this far outside reach (m) and beyond are not checked.
_BAND = 0.5
# Instants within the period at which the motion is checked (shares of it).
_CHECKS = np.array([0.25, 0.5, 0.75, 1.0])
# Penalty per metre of remaining violation, against ‖u − u_plan‖².
_SLACK_WEIGHT = 1e4
_FD_STEP = 1e-5


class _Motion:
    """The robot's motion over one period against people standing at P."""

    def __init__(self, robot, q0, nu0, period, P, d0, reach, gamma):
        self.robot, self.q0, self.nu0, self.period = robot, q0, nu0, period
        self.P, self.d0 = P, d0
        h0 = np.maximum(d0 - reach, 0.0)
        # The least d − d0 each check instant allows, (checks × people).
        self.allowed = -gamma * _CHECKS[:, None] * h0[None, :]

    def Slack(self, u):
        """(d(q(t)) − d0) − allowed at every check instant and person (≥ 0:
        kept), flat; ν ramps linearly over the period under u."""
        q = np.array(
            [ModelStep(self.robot, self.q0, self.nu0, u, s * self.period)[0]
             for s in _CHECKS]
        )  # fmt: skip
        P = np.broadcast_to(self.P, (len(q),) + self.P.shape)
        d = HumanDistances(self.robot, q, P)
        return (d - self.d0[None] - self.allowed).ravel()


def FilterCommand(
    robot, q0, nu0, u, positions, *, period: float, reach: float, gamma: float
):
    """The command ``u`` (accelerations, m), or the closest one whose motion
    over ``period`` keeps the robot's part of the DT-CBF (module doc)
    against people standing at ``positions`` (k, 2). Returns (u, filtered)."""
    q0 = np.asarray(q0, dtype=float)
    nu0 = np.asarray(nu0, dtype=float)
    u = np.asarray(u, dtype=float)
    P = np.asarray(positions, dtype=float).reshape(-1, 2)
    P = P[np.all(np.isfinite(P), axis=1)]
    ok = np.all(np.isfinite(q0)) and np.all(np.isfinite(nu0))
    if not len(P) or not ok or not np.all(np.isfinite(u)):
        return u, False
    d0 = HumanDistances(robot, q0[None], P[None])[0]
    near = d0 < reach + _BAND
    if not np.any(near):
        return u, False
    motion = _Motion(robot, q0, nu0, period, P[near], d0[near], reach, gamma)
    slack = motion.Slack(u)
    if np.all(slack >= -CLOSING_TOLERANCE):
        return u, False
    # The accelerations the limits allow over one period (ν stays within
    # its limits, as ModelStep clips it).
    lo = np.maximum(robot.nudot_lower, (robot.nu_lower - nu0) / period)
    hi = np.minimum(robot.nudot_upper, (robot.nu_upper - nu0) / period)
    lo = np.minimum(lo, hi)
    m, k = u.size, slack.size
    best, best_worst = u, slack.min()
    point = np.clip(u, lo, hi)
    for _ in range(2):  # two linearizations (SQP)
        c = motion.Slack(point)
        A = np.empty((k, m))
        for i in range(m):
            step = np.zeros(m)
            step[i] = _FD_STEP
            A[:, i] = (motion.Slack(point + step) - c) / _FD_STEP
        # min ½‖v − u‖² + w Σ s  s.t.  c + A(v − point) + s ≥ 0, s ≥ 0, v in
        # [lo, hi]; variables x = [v; s].
        Pm = np.diag(np.concatenate([np.ones(m), np.full(k, 1e-9)]))
        cost = np.concatenate([-u, np.full(k, _SLACK_WEIGHT)])
        G = -np.hstack([A, np.eye(k)])  # −(A v + s) ≤ c − A·point
        solver = piqp.DenseSolver()
        solver.settings.verbose = False
        solver.setup(
            Pm,
            cost,
            None,
            None,
            G,
            np.full(k, -np.inf),
            c - A @ point,
            np.concatenate([lo, np.zeros(k)]),
            np.concatenate([hi, np.full(k, np.inf)]),
        )
        if solver.solve() != piqp.PIQP_SOLVED:
            break
        point = np.clip(np.array(solver.result.x[:m]), lo, hi)
        worst = motion.Slack(point).min()
        if worst > best_worst:
            best, best_worst = point, worst
        if worst >= -CLOSING_TOLERANCE:
            break
    return best, True
