"""The backup-trajectory safety filter (``safety.backup_filter``).

A control step's command is the plan's first input, held for one control
period; after it the robot can at best brake. The filter checks that
whole committed motion, the first period and the braking that would
follow it to a standstill, against every tracked person moving on at the
measured velocity and against the walls, and compares it with braking at
once: for each person and each wall the command may bring the robot no
nearer than braking at once would, unless it keeps outside the margin
throughout (``safety.backup_margin`` beyond a person's disc; half the
obstacle margin from a wall, the margin's part a route may use, as in the
recovery). A command that fails is replaced by braking at once, unless
braking at once would come nearer a wall than the command (walls outrank
people, as in the plan's slack weights). The plan's barrier rows are soft
(a squeezed plan pays slack to cross them) and hold the robot's motion
only at the knots, under a linearization; the
filter is hard, on the nonlinear distances, samples within each period,
and sees the stopping distance, which a one-period check does not (a base
turning with the arm out takes longer than a period to stop).
"""

from __future__ import annotations

import numpy as np

from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.control.robot_groups import ModelStep
from sm2ith_drake.humans.robot_view import (
    FloorCapsules,
    HumanDistances,
    WallDistances,
)

# Samples per control period along the checked motion.
_SUBSTEPS = 4
# The filter does not tell apart differences below this (m).
_TOLERANCE = 1e-4
# ν counts as at rest below this (per component).
_REST = 1e-6


def BrakingAcceleration(robot, nu: np.ndarray, period: float) -> np.ndarray:
    """Drives ν toward zero as fast as the acceleration limits allow."""
    return np.clip(-np.asarray(nu) / period, robot.nudot_lower, robot.nudot_upper)


def CommittedMotion(robot, q0, nu0, u, period: float, *, max_periods: int = 50):
    """The motion a command commits the robot to: ``u`` for one period,
    then braking until at rest (at most ``max_periods`` periods), sampled
    _SUBSTEPS times per period by the MPC's model step: the states q (T, n)
    at times (1, ..., T) · period / _SUBSTEPS after now (T = 0: already at
    rest, braking). ``u`` None: braking at once."""
    dt = period / _SUBSTEPS
    q = np.asarray(q0, dtype=float)
    nu = np.asarray(nu0, dtype=float)
    states = []
    for k in range(max_periods + 1):
        if k > 0 or u is None:
            if np.all(np.abs(nu) <= _REST):
                break
            uk = BrakingAcceleration(robot, nu, period)
        else:
            uk = np.clip(
                np.asarray(u, dtype=float), robot.nudot_lower, robot.nudot_upper
            )
        for _ in range(_SUBSTEPS):
            q, nu = ModelStep(robot, q, nu, uk, dt)
            states.append(q)
    return np.asarray(states).reshape(len(states), np.size(q0))


def _AtRestUntil(q0, states, count: int) -> np.ndarray:
    """``states`` continued at rest (its last state, or q0) to ``count``."""
    last = states[-1] if len(states) else np.asarray(q0, dtype=float)
    pad = np.repeat(last[None], count - len(states), axis=0)
    return np.concatenate([states, pad]) if len(states) else pad


class BackupFilter:
    """Checks a command's committed motion against the tracked people and
    the walls (see the module docstring)."""

    def __init__(
        self,
        robot,
        *,
        period: float,
        human_radius: float,
        margin: float,
        walls=(),
        wall_margin: float = 0.0,
        people_move: bool = True,
    ):
        """``people_move`` False holds every person where measured (for
        React, whose plans predict nothing)."""
        self.people_move = people_move
        self.robot = robot
        self.period = period
        self.reach = human_radius + margin
        self.wall_margin = wall_margin
        self.walls = np.asarray(walls, dtype=float).reshape(-1, 2, 2)

    @PROFILER.Timed("backup_filter")
    def Admits(self, q0, nu0, u, humans) -> bool:
        """Whether the command ``u`` passes (module docstring). No tracked
        person, or a non-finite state: passes (the MPC's own checks handle
        a non-finite state)."""
        if humans is None or not len(humans.positions):
            return True
        q0 = np.asarray(q0, dtype=float)
        nu0 = np.asarray(nu0, dtype=float)
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(nu0))):
            return True
        p = np.asarray(humans.positions, dtype=float)
        v = np.nan_to_num(np.asarray(humans.velocities, dtype=float))
        if not self.people_move:
            v = np.zeros_like(v)
        keep = np.all(np.isfinite(p), axis=1)
        if not np.any(keep):
            return True
        p, v = p[keep], v[keep]
        mine = CommittedMotion(self.robot, q0, nu0, u, self.period)
        # Outside the margins throughout its own motion (at least one
        # sample): passes.
        mine = _AtRestUntil(q0, mine, max(len(mine), 1))
        people, walls = self._WorstBarriers(mine, p, v)
        if np.all(people >= -_TOLERANCE) and np.all(walls >= -_TOLERANCE):
            return True
        # Otherwise against braking at once, both over the same time, each
        # at rest after its motion (a person walking on keeps closing in on
        # a robot that has stopped). Braking at once stops no later than
        # the command, up to rounding, so the command's barriers mostly
        # stand as computed.
        brake = CommittedMotion(self.robot, q0, nu0, None, self.period)
        count = max(len(mine), len(brake))
        if count > len(mine):
            people, walls = self._WorstBarriers(_AtRestUntil(q0, mine, count), p, v)
        brake_people, brake_walls = self._WorstBarriers(
            _AtRestUntil(q0, brake, count), p, v
        )
        if np.any(brake_walls < np.minimum(walls, 0.0) - _TOLERANCE):
            return True  # braking would be worse against a wall
        return bool(
            np.all(people >= np.minimum(brake_people, 0.0) - _TOLERANCE)
            and np.all(walls >= np.minimum(brake_walls, 0.0) - _TOLERANCE)
        )

    def _WorstBarriers(self, states, positions, velocities):
        """Each barrier's smallest value along the sampled motion (states
        at 1, 2, ... sub-steps from now): (H,) people, distance − reach to
        each person moving on at ``velocities``, and (S,) walls, distance −
        wall margin."""
        times = np.arange(1, len(states) + 1) * (self.period / _SUBSTEPS)
        capsules = FloorCapsules(self.robot, states)
        P = positions[None] + times[:, None, None] * velocities[None]  # (T, H, 2)
        people = HumanDistances(self.robot, states, P, capsules=capsules)
        walls = WallDistances(self.robot, states, self.walls, capsules=capsules)
        return (
            np.min(people, axis=0) - self.reach,
            np.min(walls, axis=0) - self.wall_margin,
        )
