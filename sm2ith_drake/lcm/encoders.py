"""Encoders: LeafSystems that pack values into LCM messages.

The controller's side publishes the command the gate let through and the
plan (telemetry); the driver's side publishes the robot state and the motion
capture's detections. Each message's utime is the wall clock when it is
published.
"""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.control.mpc_controller import ControllerState
from sm2ith_drake.humans.messages import HumanDetections, MpcPlan
from sm2ith_drake.lcm.codecs import (
    MakeCommandMessage,
    MakeDetectionsMessage,
    MakePlanMessage,
    MakeRobotStateMessage,
)
from sm2ith_drake.lcm.command_gate import GateState
from sm2ith_drake.lcm.sm2ith_lcmtypes import (
    lcmt_sm2ith_human_detections,
    lcmt_sm2ith_plan,
    lcmt_sm2ith_robot_command,
    lcmt_sm2ith_robot_state,
)


class RobotCommandEncoder(LeafSystem):
    """Packs the gated command into an ``lcmt_sm2ith_robot_command`` (utime:
    the wall clock when it is published).

    .. pydrake_system::

        name: RobotCommandEncoder
        input_ports:
        - gated_command
        - gate_status
        output_ports:
        - lcm_message
    """

    def __init__(self, num_velocities: int):
        super().__init__()
        self._command = self.DeclareVectorInputPort("gated_command", 2 * num_velocities)
        self._gate = self.DeclareAbstractInputPort(
            "gate_status", AbstractValue.Make(GateState())
        )
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_robot_command()),
            lambda context, output: output.set_value(
                MakeCommandMessage(
                    self._command.Eval(context), self._gate.Eval(context)
                )
            ),
        )


class PlanEncoder(LeafSystem):
    """Packs the controller's plan into an ``lcmt_sm2ith_plan`` (telemetry).

    .. pydrake_system::

        name: PlanEncoder
        input_ports:
        - plan
        - controller_state
        - gate_status
        output_ports:
        - lcm_message
    """

    def __init__(self, *, time_step: float):
        super().__init__()

        self._time_step = float(time_step)
        self._plan = self.DeclareAbstractInputPort(
            "plan", AbstractValue.Make(MpcPlan())
        )
        self._ctrl = self.DeclareAbstractInputPort(
            "controller_state", AbstractValue.Make(ControllerState())
        )
        self._gate = self.DeclareAbstractInputPort(
            "gate_status", AbstractValue.Make(GateState())
        )
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_plan()),
            self._Calc,
        )

    def _Calc(self, context, output):
        output.set_value(
            MakePlanMessage(
                self._plan.Eval(context).solution,
                self._ctrl.Eval(context),
                state_utime=self._gate.Eval(context).state_utime,
                time_step=self._time_step,
            )
        )


class RobotStateEncoder(LeafSystem):
    """Packs [q; ν] into an ``lcmt_sm2ith_robot_state`` (utime: the wall
    clock when it is published).

    .. pydrake_system::

        name: RobotStateEncoder
        input_ports:
        - state
        output_ports:
        - lcm_message
    """

    def __init__(self, num_positions: int, num_velocities: int):
        super().__init__()
        self._n = num_positions
        self._x = self.DeclareVectorInputPort("state", num_positions + num_velocities)
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_robot_state()),
            lambda context, output: output.set_value(
                MakeRobotStateMessage(self._x.Eval(context), num_positions=self._n)
            ),
        )


class HumanDetectionsEncoder(LeafSystem):
    """Packs a HumanDetections frame into an ``lcmt_sm2ith_human_detections``
    (utime: the wall clock when it is published).

    .. pydrake_system::

        name: HumanDetectionsEncoder
        input_ports:
        - detections
        output_ports:
        - lcm_message
    """

    def __init__(self):
        super().__init__()
        self._frame = self.DeclareAbstractInputPort(
            "detections", AbstractValue.Make(HumanDetections())
        )
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_human_detections()),
            lambda context, output: output.set_value(
                MakeDetectionsMessage(self._frame.Eval(context))
            ),
        )
