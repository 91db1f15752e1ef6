"""HumanPredictor: the people's predicted motion, as a system of its own."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.control.prediction.predict import HumanPredictorModel, NextState
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.humans.messages import (
    HumanEstimate,
    HumanIntents,
    HumanPrediction,
    MpcPlan,
)


class HumanPredictor(LeafSystem):
    """Predicts the tracked people over the MPC's horizon under the chosen
    model (control/prediction/predict.py): ORCA forward-simulated against the
    robot's warm-start plan, constant velocity, or held.

    .. pydrake_system::

        name: HumanPredictor
        input_ports:
        - human_estimate
        - robot_state
        - plan
        - human_intents (simulation only, optional)
        output_ports:
        - human_prediction
        - last_prediction

    ``human_prediction`` (a HumanPrediction) is computed from the inputs and
    what the predictor remembers: the people's slots, their ORCA neighbour
    sets (with hysteresis) and their filtered preferred velocities. That
    memory is abstract state, committed by a periodic update at the control
    rate with the same inputs the controller's update reads at that instant.
    ``plan`` is the HierarchicalMpc's plan (its output depends on its state
    only, so there is no algebraic loop). ``human_intents`` carries the
    preferred velocities only a simulation knows (people who walk as the
    model says); on hardware it does not exist. ``last_prediction`` is the
    prediction committed at the last update (state only, for drawing: it
    costs nothing to evaluate between control steps).
    """

    def __init__(
        self,
        robot,
        config,
        *,
        horizon: int,
        time_step: float,
        control_period: float,
        obstacle_segments=(),
        human_radius: float = 0.3,
        with_intents: bool = False,
        guard_deviation: float = 0.0,
        guard_hold: float = 0.0,
        guard_gap: float = 0.0,
        guard_approach: float = 0.0,
    ):
        """``config`` is a PredictionConfig; ``horizon`` and ``time_step``
        the MPC's; ``with_intents`` declares the ``human_intents`` input;
        ``guard_deviation``, ``guard_hold``, ``guard_gap``, ``guard_approach``
        as in SafetyConfig."""
        super().__init__()
        self.model = HumanPredictorModel(
            config,
            horizon=horizon,
            time_step=time_step,
            control_period=control_period,
            robot=robot,
            obstacles=obstacle_segments,
            human_radius=human_radius,
            guard_deviation=guard_deviation,
            guard_hold=guard_hold,
            guard_gap=guard_gap,
            guard_approach=guard_approach,
        )
        n, m = robot.num_positions, robot.num_velocities
        self._n = n
        self._estimate = self.DeclareAbstractInputPort(
            "human_estimate", AbstractValue.Make(HumanEstimate())
        )
        self._robot_state = self.DeclareVectorInputPort("robot_state", n + m)
        self._plan = self.DeclareAbstractInputPort(
            "plan", AbstractValue.Make(MpcPlan())
        )
        self._intents = None
        if with_intents:
            self._intents = self.DeclareAbstractInputPort(
                "human_intents", AbstractValue.Make(HumanIntents())
            )
        self._state = self.DeclareAbstractState(
            AbstractValue.Make(self.model.InitialState())
        )
        self._prediction = self.DeclareAbstractOutputPort(
            "human_prediction",
            lambda: AbstractValue.Make(HumanPrediction()),
            self._CalcPrediction,
        )
        self.DeclareAbstractOutputPort(
            "last_prediction",
            lambda: AbstractValue.Make(HumanPrediction()),
            self._CalcLastPrediction,
            {self.abstract_state_ticket(self._state)},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(control_period, 0.0, self._Update)

    def _Predict(self, context):
        x = np.asarray(self._robot_state.Eval(context))
        plan = self._plan.Eval(context)
        return self.model.Predict(
            context.get_abstract_state(self._state).get_value(),
            estimate=self._estimate.Eval(context),
            intents=None if self._intents is None else self._intents.Eval(context),
            q0=x[: self._n],
            nu0=x[self._n :],
            warm_start_inputs=plan.warm_start_inputs,
            last_solution=plan.solution,
        )

    @PROFILER.Timed("predictor")
    def _CalcPrediction(self, context, output):
        output.set_value(self._Predict(context)[0])

    def _CalcLastPrediction(self, context, output):
        last = context.get_abstract_state(self._state).get_value().last_prediction
        output.set_value(last if last is not None else HumanPrediction())

    def _Update(self, context, state):
        # The output is cached: the controller's update at this instant has
        # evaluated it already (same inputs, same state), so this re-uses it.
        prediction = self._prediction.Eval(context)
        state.get_mutable_abstract_state(self._state).set_value(NextState(prediction))

    def GetPredictorState(self, context):
        return context.get_abstract_state(self._state).get_value()
