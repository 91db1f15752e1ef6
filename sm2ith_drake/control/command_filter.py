"""A last check on the command before it goes out (``safety.command_filter``,
`safe` variant only): the robot's own motion over the next control period
does not close in on anyone already inside the barrier's margin.

The DT-CBF rows carry slack (an exact penalty), so when the barriers cannot
all hold, e.g. a person walking at the robot in a door with another person
beside it, the plan trades one person's margin for another's and may drive
the robot into someone standing within reach. This filter takes the
people measured inside ``reach`` (human radius plus margin, from the
robot's nearest body) as they stand now and finds the command closest to
the plan's whose one-period motion does not bring any body nearer to them,
to first order, by a small QP (soft constraints: when braking cannot avoid
some closing, the least closing is taken); the result is checked on the
nonlinear distances. Only the robot's motion is constrained: people may
still walk into a robot that holds its ground.
"""

from __future__ import annotations

import numpy as np
import piqp

from sm2ith_drake.control.robot_groups import ModelStep
from sm2ith_drake.humans.robot_view import HumanDistances

# Closing below this (m per control period) is not corrected.
CLOSING_TOLERANCE = 1e-4
# Penalty per metre of remaining closing, against ‖u − u_plan‖².
_SLACK_WEIGHT = 1e4
_FD_STEP = 1e-5


def _Closing(robot, q0, nu0, u, period, positions, d0):
    """d(q1, p) − d(q0, p) for each person p, q1 one period of ``u`` on."""
    q1, _ = ModelStep(robot, q0, nu0, u, period)
    return HumanDistances(robot, q1[None], positions[None])[0] - d0


def FilterCommand(robot, q0, nu0, u, positions, *, period: float, reach: float):
    """The command ``u`` (accelerations, m) or, if its motion over
    ``period`` would bring the robot nearer to anyone at ``positions`` (k, 2)
    measured within ``reach`` of its nearest body, the closest command whose
    motion does not (as far as the limits allow). Returns (u, filtered)."""
    q0 = np.asarray(q0, dtype=float)
    nu0 = np.asarray(nu0, dtype=float)
    u = np.asarray(u, dtype=float)
    P = np.asarray(positions, dtype=float).reshape(-1, 2)
    P = P[np.all(np.isfinite(P), axis=1)]
    ok = np.all(np.isfinite(q0)) and np.all(np.isfinite(nu0))
    if not len(P) or not ok or not np.all(np.isfinite(u)):
        return u, False
    d0 = HumanDistances(robot, q0[None], P[None])[0]
    close = d0 < reach
    if not np.any(close):
        return u, False
    P, d0 = P[close], d0[close]
    closing = _Closing(robot, q0, nu0, u, period, P, d0)
    if np.all(closing >= -CLOSING_TOLERANCE):
        return u, False
    # The accelerations the limits allow over one period (ν stays within
    # its limits, as ModelStep clips it).
    lo = np.maximum(robot.nudot_lower, (robot.nu_lower - nu0) / period)
    hi = np.minimum(robot.nudot_upper, (robot.nu_upper - nu0) / period)
    lo = np.minimum(lo, hi)
    m, k = u.size, len(P)
    best, best_worst = u, closing.min()
    point = np.clip(u, lo, hi)
    for _ in range(2):  # two linearizations (SQP)
        c = _Closing(robot, q0, nu0, point, period, P, d0)
        A = np.empty((k, m))
        for i in range(m):
            step = np.zeros(m)
            step[i] = _FD_STEP
            A[:, i] = (_Closing(robot, q0, nu0, point + step, period, P, d0) - c) / (
                _FD_STEP
            )
        # min ½‖v − u‖² + w Σ s  s.t.  c + A(v − point) + s ≥ 0, s ≥ 0, v in
        # [lo, hi]; variables x = [v; s].
        Pm = np.diag(np.concatenate([np.ones(m), np.full(k, 1e-9)]))
        cost = np.concatenate([-u, np.full(k, _SLACK_WEIGHT)])
        G = -np.hstack([A, np.eye(k)])  # −(A v + s) ≤ c − A·point
        h = c - A @ point
        solver = piqp.DenseSolver()
        solver.settings.verbose = False
        x_lo = np.concatenate([lo, np.zeros(k)])
        x_hi = np.concatenate([hi, np.full(k, np.inf)])
        solver.setup(Pm, cost, None, None, G, np.full(k, -np.inf), h, x_lo, x_hi)
        if solver.solve() != piqp.PIQP_SOLVED:
            break
        point = np.clip(np.array(solver.result.x[:m]), lo, hi)
        worst = _Closing(robot, q0, nu0, point, period, P, d0).min()
        if worst > best_worst:
            best, best_worst = point, worst
        if worst >= -CLOSING_TOLERANCE:
            break
    return best, True
