"""HierarchicalMpc: the controller LeafSystem over control/mpc_controller.py."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.control.mpc_controller import ControllerState, MpcController
from sm2ith_drake.humans.messages import HumanPrediction, MpcPlan
from sm2ith_drake.planning.sequence import TaskReferences
from sm2ith_drake.scenario import ControllerConfig


class HierarchicalMpc(LeafSystem):
    """Runs the hierarchical MPC at the control rate.

    The solve happens in a periodic unrestricted update and its outcome (plan,
    command, counters, timing) is held in abstract state; outputs only read
    that state (so no output depends on an input directly).

    .. pydrake_system::

        name: HierarchicalMpc
        input_ports:
        - robot_state
        - task_references
        - human_prediction (with a predictor)
        output_ports:
        - command
        - plan
        - controller_state

    ``robot_state`` is [q; ν]; ``human_prediction`` is the HumanPredictor's
    output (for CVMM and React the prediction itself; for SM²ITH the warm
    start and the neighbour structure the KKT embedding refines jointly with
    the robot's plan); ``command`` is [u = ν̇; ν_cmd]; ``plan`` is an MpcPlan;
    ``controller_state`` the whole ControllerState (counters and the last
    StepRecord).
    """

    def __init__(
        self,
        robot,
        tasks,
        config: ControllerConfig,
        *,
        prediction=None,
        safety=None,
        obstacles=(),
    ):
        super().__init__()
        self.controller = MpcController(
            robot,
            tasks,
            config,
            prediction=prediction,
            safety=safety,
            obstacles=obstacles,
        )
        self._n, self._m = robot.num_positions, robot.num_velocities
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", self._n + self._m
        )
        self._references = self.DeclareAbstractInputPort(
            "task_references", AbstractValue.Make(TaskReferences())
        )
        self._prediction = None
        if prediction is not None:
            self._prediction = self.DeclareAbstractInputPort(
                "human_prediction", AbstractValue.Make(HumanPrediction())
            )
        self._state = self.DeclareAbstractState(
            AbstractValue.Make(self.controller.InitialState())
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(
            self.controller.period, 0.0, self._Update
        )
        state_only = {self.abstract_state_ticket(self._state)}
        self.DeclareVectorOutputPort(
            "command", 2 * self._m, self._CalcCommand, state_only
        )
        self.DeclareAbstractOutputPort(
            "plan",
            lambda: AbstractValue.Make(MpcPlan()),
            self._CalcPlan,
            state_only,
        )
        self.DeclareAbstractOutputPort(
            "controller_state",
            lambda: AbstractValue.Make(ControllerState()),
            self._CalcControllerState,
            state_only,
        )

    def _Update(self, context, state):
        x = self._robot_state.Eval(context)
        refs = self._references.Eval(context)
        old = context.get_abstract_state(self._state).get_value()
        new = self.controller.Step(
            old,
            time_now=context.get_time(),
            q0=x[: self._n],
            nu0=x[self._n :],
            targets=refs.targets,
            done_tolerances=refs.done_tolerances,
            prediction=None
            if self._prediction is None
            else self._prediction.Eval(context),
        )
        state.get_mutable_abstract_state(self._state).set_value(new)

    def GetControllerState(self, context) -> ControllerState:
        return context.get_abstract_state(self._state).get_value()

    def _CalcCommand(self, context, output):
        s = self.GetControllerState(context)
        output.SetFromVector(np.concatenate([s.command_u, s.command_nu]))

    def _CalcPlan(self, context, output):
        output.set_value(self.controller.Plan(self.GetControllerState(context)))

    def _CalcControllerState(self, context, output):
        output.set_value(self.GetControllerState(context))
