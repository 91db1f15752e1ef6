"""KinematicRobot: the simulated robot, integrating the commanded input."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.robots.planar_base import NUM_BASE_POSITIONS, ArmVelocityIndex


class KinematicRobot(LeafSystem):
    """A kinematic mobile manipulator: q̇ = G(q) ν, ν̇ = u (Section III).

    The command u is clipped to the acceleration limits, ν to the velocity
    limits and q to the joint limits (a joint at its limit stops), so the
    simulated robot can never exceed its limits whatever it is told. A
    non-finite command is treated as a braking command.

    .. pydrake_system::

        name: KinematicRobot
        input_ports:
        - command
        output_ports:
        - state

    ``command`` is [u (m); ν_cmd (m)] (only u is integrated here; ν_cmd is
    what a velocity-controlled robot would track). ``state`` is [q (n); ν (m)].
    """

    def __init__(self, robot, *, initial_q, initial_nu=None, time_step: float = 0.01):
        super().__init__()
        self._robot = robot
        n, m = robot.num_positions, robot.num_velocities
        self._n, self._m = n, m
        self._h = float(time_step)
        x0 = np.zeros(n + m)
        x0[:n] = initial_q
        if initial_nu is not None and len(initial_nu):
            x0[n:] = initial_nu
        self._command = self.DeclareVectorInputPort("command", 2 * m)
        state = self.DeclareDiscreteState(x0)
        self.DeclarePeriodicDiscreteUpdateEvent(self._h, 0.0, self._Integrate)
        self.DeclareStateOutputPort("state", state)

    def _Integrate(self, context, discrete_state):
        robot, n, h = self._robot, self._n, self._h
        x = context.get_discrete_state_vector().CopyToVector()
        q, nu = x[:n], x[n:]
        if self._command.HasValue(context):
            u = self._command.Eval(context)[: self._m]
        else:
            u = np.zeros(self._m)
        if not np.all(np.isfinite(u)):
            u = -nu / h
        u = np.clip(u, robot.nudot_lower, robot.nudot_upper)
        nu_next = np.clip(nu + h * u, robot.nu_lower, robot.nu_upper)
        q_next = q + h * robot.G(q) @ nu_next
        clipped = np.clip(q_next, robot.q_lower, robot.q_upper)
        # A joint that hits its limit stops (arm joints map 1:1 to ν).
        arm = slice(NUM_BASE_POSITIONS, None)
        hit = NUM_BASE_POSITIONS + np.nonzero(clipped[arm] != q_next[arm])[0]
        nu_next[ArmVelocityIndex(robot, hit)] = 0.0
        discrete_state.set_value(np.concatenate([clipped, nu_next]))
