"""The simulated people and how the controller perceives them.

CrowdSimulator ─human_truth─► MocapSensor ─detections─► HumanEstimator
─human_estimate─► HierarchicalMpc.
"""

import copy

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.humans.crowd import InitialCrowdState, StepCrowd
from sm2ith_drake.humans.messages import HumanDetections, HumanEstimate, HumanIntents
from sm2ith_drake.humans.tracking import HumanTracks
from sm2ith_drake.planning.sequence import TaskReferences


class CrowdSimulator(LeafSystem):
    """Moves the simulated humans with their behaviours (humans/crowd.py).

    .. pydrake_system::

        name: CrowdSimulator
        input_ports:
        - robot_state
        - task_references (optional)
        output_ports:
        - human_truth
        - human_intents

    ``human_truth`` is a HumanEstimate with the true positions and
    velocities (ids 0 … H−1, in scenario order); ``human_intents`` (a
    HumanIntents, for the predictor's simulation-only input) the preferred
    velocities of the people who walk as the prediction model says (NaN for the rest).
    ``task_references`` (the TaskPlanner's) tells where the robot's task
    sequence is; people with a ``start_phase`` or ``waypoint_phases`` need
    it connected. When each of their phases was entered is kept in the
    crowd's abstract state.
    """

    def __init__(
        self,
        robot,
        humans,
        *,
        obstacle_segments,
        time_step: float = 0.05,
        tau: float = 2.0,
        tau_obs: float = 0.5,
        model=None,
        phases=(),
    ):
        """``model``: the PredictionConfig that "relaxed_orca" people follow;
        ``phases``: the names of the task sequence's phases, in order (the
        ``start_phase`` and ``waypoint_phases`` of a person must be among
        them)."""
        super().__init__()
        self._model = model
        self._robot = robot
        self._humans = list(humans)
        self._phases = tuple(phases)
        self._needs_phase = False
        for j, h in enumerate(self._humans):
            gates = {"start_phase": h.start_phase}
            gates.update(
                (f"waypoint_phases[{k}]", name)
                for k, name in enumerate(h.waypoint_phases)
            )
            for field_name, name in gates.items():
                if name and name not in self._phases:
                    raise ValueError(
                        f"humans[{j}].{field_name} '{name}' is not a phase "
                        f"of the sequence {list(self._phases)}"
                    )
                self._needs_phase |= bool(name)
        self._segments = np.asarray(obstacle_segments, dtype=float).reshape(-1, 2, 2)
        self._dt = float(time_step)
        self._tau, self._tau_obs = tau, tau_obs
        n, m = robot.num_positions, robot.num_velocities
        self._n = n
        self._x = self.DeclareVectorInputPort("robot_state", n + m)
        self._references = self.DeclareAbstractInputPort(
            "task_references", AbstractValue.Make(TaskReferences())
        )
        self._state = self.DeclareAbstractState(
            AbstractValue.Make(InitialCrowdState(self._humans))
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(self._dt, 0.0, self._Step)
        self.DeclareAbstractOutputPort(
            "human_truth", lambda: AbstractValue.Make(HumanEstimate()), self._Output
        )
        self.DeclareAbstractOutputPort(
            "human_intents",
            lambda: AbstractValue.Make(HumanIntents()),
            self._OutputIntents,
        )

    def _Step(self, context, state):
        crowd = context.get_abstract_state(self._state).get_value()
        x = self._x.Eval(context)
        q, nu = x[: self._n], x[self._n :]
        qdot = self._robot.G(q) @ nu
        kin = self._robot.CalcKinematics(q)
        bodies = (kin.capsule_points[0, :, :, :2], self._robot.capsule_radii)
        phase_index = None
        if self._references.HasValue(context):
            phase_index = self._references.Eval(context).phase_index
        elif self._needs_phase:
            raise RuntimeError(
                "CrowdSimulator: people with a start_phase or waypoint_phases "
                "need the task_references input connected (the TaskPlanner's "
                "output)"
            )
        new = StepCrowd(
            self._humans,
            copy.deepcopy(crowd),
            time=context.get_time(),
            dt=self._dt,
            robot_position=q[:2],
            robot_velocity=qdot[:2],
            robot_radius=self._robot.model.base_radius,
            obstacle_segments=self._segments,
            tau=self._tau,
            tau_obs=self._tau_obs,
            robot_bodies=bodies,
            model=self._model,
            phases=self._phases,
            phase_index=phase_index,
        )
        state.get_mutable_abstract_state(self._state).set_value(new)

    def _Output(self, context, output):
        crowd = context.get_abstract_state(self._state).get_value()
        output.set_value(
            HumanEstimate(
                ids=np.arange(len(self._humans)),
                positions=crowd.positions,
                velocities=crowd.velocities,
            )
        )

    def _OutputIntents(self, context, output):
        crowd = context.get_abstract_state(self._state).get_value()
        output.set_value(
            HumanIntents(
                ids=np.arange(len(self._humans)),
                preferred_velocities=crowd.preferred,
            )
        )


class MocapSensor(LeafSystem):
    """Motion capture: the true positions with Gaussian noise and random
    dropouts (a missing human in a frame), at a fixed rate.

    .. pydrake_system::

        name: MocapSensor
        input_ports:
        - human_truth
        output_ports:
        - detections
    """

    def __init__(
        self, *, period: float, noise: float, dropout_probability: float, seed: int = 0
    ):
        super().__init__()
        self._noise = float(noise)
        self._dropout = float(dropout_probability)
        self._seed = seed
        self._truth = self.DeclareAbstractInputPort(
            "human_truth", AbstractValue.Make(HumanEstimate())
        )
        self._frame = self.DeclareAbstractState(AbstractValue.Make(HumanDetections()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Measure)
        self.DeclareAbstractOutputPort(
            "detections",
            lambda: AbstractValue.Make(HumanDetections()),
            lambda context, output: output.set_value(
                context.get_abstract_state(self._frame).get_value()
            ),
        )

    def _Measure(self, context, state):
        truth = self._truth.Eval(context)
        # A generator per frame, seeded by (seed, frame): reproducible runs.
        frame = int(round(context.get_time() * 1e6))
        rng = np.random.default_rng([self._seed, frame])
        seen = rng.random(len(truth.ids)) >= self._dropout
        noisy = truth.positions + rng.normal(
            scale=self._noise, size=truth.positions.shape
        )
        state.get_mutable_abstract_state(self._frame).set_value(
            HumanDetections(
                time=context.get_time(), ids=truth.ids[seen], positions=noisy[seen]
            )
        )


class HumanEstimator(LeafSystem):
    """A constant-velocity Kalman filter per tracked human id.

    Missed detections only predict (the covariance grows); new ids start a
    track; tracks unseen for ``track_timeout`` are dropped; NaN, infinite or
    implausible detections are rejected and counted.

    .. pydrake_system::

        name: HumanEstimator
        input_ports:
        - detections
        output_ports:
        - human_estimate
    """

    def __init__(
        self,
        *,
        period: float,
        measurement_noise: float,
        acceleration_noise: float,
        track_timeout: float,
    ):
        super().__init__()

        self._make_tracks = lambda: HumanTracks(
            measurement_noise=max(measurement_noise, 1e-3),
            acceleration_noise=acceleration_noise,
            timeout=track_timeout,
        )
        self._detections = self.DeclareAbstractInputPort(
            "detections", AbstractValue.Make(HumanDetections())
        )
        self._tracks = self.DeclareAbstractState(
            AbstractValue.Make(self._make_tracks())
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Update)
        self.DeclareAbstractOutputPort(
            "human_estimate", lambda: AbstractValue.Make(HumanEstimate()), self._Output
        )

    def _Update(self, context, state):
        frame = self._detections.Eval(context)
        tracks = context.get_abstract_state(self._tracks).get_value()
        if frame.time <= tracks.last_frame_time:
            return  # no new frame since the last update
        tracks = copy.deepcopy(tracks)
        detections = {
            int(i): p for i, p in zip(frame.ids, frame.positions, strict=True)
        }
        # Fused at the time the frame was taken, not when it is read.
        tracks.Step(frame.time, detections)
        state.get_mutable_abstract_state(self._tracks).set_value(tracks)

    def GetTracks(self, context):
        return context.get_abstract_state(self._tracks).get_value()

    def _Output(self, context, output):
        tracks = self.GetTracks(context)
        ids, positions, velocities = tracks.Estimates(context.get_time())
        output.set_value(
            HumanEstimate(ids=ids, positions=positions, velocities=velocities)
        )
