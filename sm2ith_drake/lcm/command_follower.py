"""The driver's robot: it follows the last valid command, and brakes when
commands stop coming (its own watchdog)."""

from __future__ import annotations

import time

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.control.backup import BrakingAcceleration
from sm2ith_drake.lcm.receivers import ReceiverState


def FollowCommand(robot, nu, velocity, acceleration, *, time_step: float):
    """The acceleration u a velocity-controlled robot applies for one
    ``time_step``: ν moves toward ``velocity`` at the rate |acceleration|
    (the robot's acceleration limit where the command gives none) and stops
    there, so a command that is held longer than the controller's period
    does not overshoot."""
    nu = np.asarray(nu, dtype=float)
    rate = np.abs(np.asarray(acceleration, dtype=float))
    rate = np.where(rate > 1e-9, rate, robot.nudot_upper)
    return np.clip((np.asarray(velocity, dtype=float) - nu) / time_step, -rate, rate)


class CommandFollower(LeafSystem):
    """Turns the last valid command into KinematicRobot's input.

    .. pydrake_system::

        name: CommandFollower
        input_ports:
        - command_status
        - robot_state
        output_ports:
        - command

    ``command`` is [u; ν_cmd] with u from :func:`FollowCommand`; with no
    command yet or none for ``command_timeout`` seconds (simulation or wall
    clock), ν_cmd = 0 and u brakes as hard as the limits allow.
    """

    def __init__(self, robot, *, time_step: float, command_timeout: float):
        super().__init__()
        self._robot = robot
        self._h = float(time_step)
        self._timeout = float(command_timeout)
        n, m = robot.num_positions, robot.num_velocities
        self._n, self._m = n, m
        self._status = self.DeclareAbstractInputPort(
            "command_status", AbstractValue.Make(ReceiverState())
        )
        self._x = self.DeclareVectorInputPort("robot_state", n + m)
        self.DeclareVectorOutputPort("command", 2 * m, self._Calc)

    def _Calc(self, context, output):
        nu = np.array(self._x.Eval(context))[self._n :]
        status = self._status.Eval(context)
        msg = status.value
        if msg is None or status.Age(context.get_time(), time.time()) > self._timeout:
            u = BrakingAcceleration(self._robot, nu, self._h)
            output.SetFromVector(np.concatenate([u, np.zeros(self._m)]))
            return
        u = FollowCommand(
            self._robot, nu, msg.velocity, msg.acceleration, time_step=self._h
        )
        output.SetFromVector(np.concatenate([u, msg.velocity]))
