"""The command gate: the controller's command goes out only while the inputs
it was computed from are fresh; otherwise a slowed command or a stop.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.control.backup import BrakingAcceleration
from sm2ith_drake.lcm.receivers import ReceiverState
from sm2ith_drake.lcm.sm2ith_lcmtypes import lcmt_sm2ith_robot_command

MODE_CONTROL = lcmt_sm2ith_robot_command.MODE_CONTROL
MODE_SLOWED = lcmt_sm2ith_robot_command.MODE_SLOWED
MODE_STOP = lcmt_sm2ith_robot_command.MODE_STOP
MODE_NAMES = {MODE_CONTROL: "control", MODE_SLOWED: "slowed", MODE_STOP: "stop"}


@dataclass
class GateCounters:
    """Control steps by what was sent."""

    control: int = 0
    slowed: int = 0
    stopped: int = 0
    # Steps stopped because the robot state was stale or missing, and
    # because the people were unknown (detections too old).
    stale_state: int = 0
    people_unknown: int = 0


@dataclass
class GateState:
    """The CommandGate's decision at the last control step."""

    mode: int = MODE_STOP
    speed_scale: float = 0.0
    reason: str = "no control step yet"
    # ν of the state the step used (for braking and scaling).
    nu: np.ndarray | None = None
    # Timing telemetry (µs): the state's own utime, when it was received
    # and when the control step read it (wall clock).
    state_utime: int = 0
    state_receive_utime: int = 0
    control_utime: int = 0
    counters: GateCounters = field(default_factory=GateCounters)


def GateCommand(
    robot, command, nu, *, mode: int, speed_scale: float, period: float
) -> np.ndarray:
    """The command [u; ν_cmd] actually sent, given the controller's
    ``command`` and the gate's decision.

    - control: unchanged;
    - slowed: ν_cmd scaled by ``speed_scale`` (the base keeps its path: v and
      ω scale together), u the acceleration that reaches it in one period;
    - stop (or a non-finite command): ν_cmd = 0 and u brakes within the
      acceleration limits.
    """
    m = robot.num_velocities
    command = np.asarray(command, dtype=float)
    nu = np.nan_to_num(np.zeros(m) if nu is None else np.asarray(nu, dtype=float))
    if mode == MODE_STOP or not np.all(np.isfinite(command)):
        return np.concatenate([BrakingAcceleration(robot, nu, period), np.zeros(m)])
    if mode == MODE_SLOWED:
        nu_cmd = speed_scale * command[m:]
        u = np.clip((nu_cmd - nu) / period, robot.nudot_lower, robot.nudot_upper)
        return np.concatenate([u, nu_cmd])
    return command.copy()


class CommandGate(LeafSystem):
    """Lets the controller's command through only while its inputs are fresh.

    At every control step (the controller's period, same instants) it reads
    how old the robot state and the detections are; the command published
    after that step is then (see :func:`GateCommand`):

    - a stop if the robot state is missing or older than ``state_timeout``,
      or the detections are older than ``detection_stop_timeout`` (the people
      are no longer known);
    - slowed by ``stale_speed_scale`` if the detections are older than
      ``detection_timeout``;
    - the controller's command otherwise.

    .. pydrake_system::

        name: CommandGate
        input_ports:
        - command
        - robot_state
        - state_status
        - detections_status (with people)
        output_ports:
        - gated_command
        - gate_status
    """

    def __init__(
        self,
        robot,
        *,
        period: float,
        state_timeout: float,
        with_people: bool = False,
        detection_timeout: float = math.inf,
        detection_stop_timeout: float = math.inf,
        stale_speed_scale: float = 0.3,
    ):
        super().__init__()
        self._robot = robot
        self._period = float(period)
        self._state_timeout = float(state_timeout)
        self._detection_timeout = float(detection_timeout)
        self._detection_stop_timeout = float(detection_stop_timeout)
        self._scale = float(stale_speed_scale)
        n, m = robot.num_positions, robot.num_velocities
        self._n, self._m = n, m
        self._command = self.DeclareVectorInputPort("command", 2 * m)
        self._x = self.DeclareVectorInputPort("robot_state", n + m)
        self._state_status = self.DeclareAbstractInputPort(
            "state_status", AbstractValue.Make(ReceiverState())
        )
        self._detections_status = None
        if with_people:
            self._detections_status = self.DeclareAbstractInputPort(
                "detections_status", AbstractValue.Make(ReceiverState())
            )
        self._gate = self.DeclareAbstractState(AbstractValue.Make(GateState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(self._period, 0.0, self._Decide)
        self.DeclareVectorOutputPort("gated_command", 2 * m, self._CalcCommand)
        self.DeclareAbstractOutputPort(
            "gate_status",
            lambda: AbstractValue.Make(GateState()),
            lambda context, output: output.set_value(self.GetGateState(context)),
        )

    def GetGateState(self, context) -> GateState:
        return context.get_abstract_state(self._gate).get_value()

    def _Decide(self, context, state):
        wall = time.time()
        now = context.get_time()
        old = self.GetGateState(context)
        new = GateState(counters=copy.copy(old.counters))
        new.control_utime = int(wall * 1e6)
        robot_status = self._state_status.Eval(context)
        x = np.array(self._x.Eval(context))
        new.nu = x[self._n :]
        new.state_utime = robot_status.utime
        if np.isfinite(robot_status.receive_wall):
            new.state_receive_utime = int(robot_status.receive_wall * 1e6)
        mode, scale, reason = MODE_CONTROL, 1.0, ""
        detection_age = -math.inf
        if self._detections_status is not None:
            detection_age = self._detections_status.Eval(context).Age(now, wall)
        if robot_status.value is None:
            mode, reason = MODE_STOP, "no robot state received"
            new.counters.stale_state += 1
        elif (age := robot_status.Age(now, wall)) > self._state_timeout:
            mode, reason = MODE_STOP, f"robot state {age:.3f} s old"
            new.counters.stale_state += 1
        elif detection_age > self._detection_stop_timeout:
            mode, reason = MODE_STOP, "no human detections (people unknown)"
            new.counters.people_unknown += 1
        elif detection_age > self._detection_timeout:
            mode, scale = MODE_SLOWED, self._scale
            reason = f"human detections {detection_age:.3f} s old"
        if mode == MODE_STOP:
            scale = 0.0
            new.counters.stopped += 1
        elif mode == MODE_SLOWED:
            new.counters.slowed += 1
        else:
            new.counters.control += 1
        new.mode, new.speed_scale, new.reason = mode, scale, reason
        state.get_mutable_abstract_state(self._gate).set_value(new)

    def _CalcCommand(self, context, output):
        gate = self.GetGateState(context)
        output.SetFromVector(
            GateCommand(
                self._robot,
                self._command.Eval(context),
                gate.nu,
                mode=gate.mode,
                speed_scale=gate.speed_scale,
                period=self._period,
            )
        )
