"""The human predictor as a pure function of (state, inputs): the math behind
the HumanPredictor system.

Each control step it filters the people's preferred velocities, keeps them in
their slots, chooses each person's ORCA neighbours, and predicts everyone's
motion over the horizon under the configured model:

- ``react``: held where they are (no prediction);
- ``cvmm``: constant velocity;
- ``orca_kkt``: every person's relaxed-ORCA QP forward-simulated against
  the robot's warm-start plan (the previous plan shifted, rolled out from
  the measured state). This is the warm start and the structure the MPC's
  KKT embedding then refines jointly with the robot's plan (eq. smith).
"""

import time

import numpy as np

from sm2ith_drake.control.prediction.base import (
    ConstantVelocityPrediction,
    HeldPrediction,
)
from sm2ith_drake.control.prediction.intent import SteerAroundWalls
from sm2ith_drake.control.prediction.orca_model import OrcaModel
from sm2ith_drake.control.prediction.reciprocity import (
    EstimatedShares,
    Overtaking,
    ShareObservations,
    UpdateEvidence,
)
from sm2ith_drake.control.prediction.slots import (
    AssignSlots,
    DefaultNeighbors,
    FilterPreferredVelocities,
    PersonalMaxSpeeds,
    PredictedNow,
    PredictorState,
    SelectNeighbors,
    UpdateGuards,
)
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.control.robot_groups import Rollout
from sm2ith_drake.humans.messages import HumanEstimate, HumanIntents, HumanPrediction
from sm2ith_drake.humans.robot_view import HumanDistances
from sm2ith_drake.scenario import PREDICTORS


class HumanPredictorModel:
    """Predicts the people for the MPC (module doc)."""

    def __init__(
        self,
        config,
        *,
        horizon: int,
        time_step: float,
        control_period: float,
        robot,
        obstacles=(),
        human_radius: float = 0.3,
        guard_deviation: float = 0.0,
        guard_hold: float = 0.0,
        guard_gap: float = 0.0,
        guard_approach: float = 0.0,
    ):
        """``config`` is a PredictionConfig; ``horizon``, ``time_step`` are
        the MPC's; ``obstacles`` (S, 2, 2) wall segments; ``guard_deviation``,
        ``guard_hold``, ``guard_gap`` and ``guard_approach`` as in
        SafetyConfig (whom the MPC's guard holds)."""
        if config.predictor not in PREDICTORS:
            raise ValueError(f"unknown predictor '{config.predictor}'")
        self.config = config
        self.N = horizon
        self.dt = time_step
        self.robot = robot
        self.num_slots = int(config.max_humans)
        tau = config.preferred_velocity_time_constant
        self._alpha = 1.0 if tau <= 0 else control_period / (tau + control_period)
        self.control_period = control_period
        self._share_decay = float(np.exp(-control_period / config.reciprocity.memory))
        self.guard_deviation = float(guard_deviation)
        self.guard_gap = float(guard_gap)
        self.guard_approach = float(guard_approach)
        self.human_radius = float(human_radius)
        self.guard_hold_steps = max(1, int(np.ceil(guard_hold / control_period - 1e-9)))
        self.orca = None
        num_neighbors = 0
        if config.predictor == "orca_kkt":
            self.orca = OrcaModel(
                config,
                horizon=horizon,
                time_step=time_step,
                robot=robot,
                obstacles=obstacles,
                human_radius=human_radius,
            )
            num_neighbors = self.orca.num_neighbors
        self._initial_neighbors = DefaultNeighbors(self.num_slots, num_neighbors)

    def InitialState(self) -> PredictorState:
        return PredictorState(
            slot_ids=np.full(self.num_slots, -1),
            neighbors=self._initial_neighbors.copy(),
        )

    def Predict(
        self,
        state: PredictorState,
        *,
        estimate: HumanEstimate | None,
        intents: HumanIntents | None = None,
        q0=None,
        nu0=None,
        warm_start_inputs=None,
        last_solution=None,
    ) -> tuple[HumanPrediction, PredictorState]:
        """This step's prediction and the state after it (``state`` is not
        changed). The ORCA model needs the robot's measured state (q0, ν0)
        and the warm-start inputs (N, m) to simulate the people against;
        without them (or with a non-finite state) its prediction holds the
        people where they are and carries no actions. ``last_solution`` (the
        controller's last MpcSolution, made one control period ago) is what
        the guard judges the people's motion against."""
        start = time.perf_counter()
        cfg = self.config
        preferred = FilterPreferredVelocities(
            state.preferred_velocities, estimate, intents, self._alpha
        )
        # Who is nearest matters with more people than slots, and to the
        # guard gap; measured once for both.
        crowded = estimate is not None and len(estimate.ids) > self.num_slots
        distances = (
            self._Distances(estimate, q0) if crowded or self.guard_gap > 0 else None
        )
        slots = AssignSlots(
            state.slot_ids,
            estimate,
            preferred,
            distances=distances if crowded else None,
            hysteresis=cfg.neighbor_hysteresis,
            num_extra=cfg.max_extra_humans,
        )
        if (
            cfg.predictor == "orca_kkt"
            and cfg.steer_around_walls
            and len(self.orca.segments)
        ):
            slots.v_pref = SteerAroundWalls(
                slots.p0,
                slots.v_pref,
                self.orca.segments,
                self.human_radius,
                lookahead=self.N * self.dt,
            )
        slots.max_speed = PersonalMaxSpeeds(slots, cfg)
        neighbors = state.neighbors
        actions = multipliers = shares = None
        behind = np.zeros(self.num_slots, dtype=bool)
        evidence = {}
        if cfg.predictor == "cvmm":
            positions = ConstantVelocityPrediction(slots.p0, slots.v0, self.N, self.dt)
        else:
            positions = HeldPrediction(slots.p0, self.N)
        if self.orca is not None:
            neighbors = SelectNeighbors(
                state.neighbors,
                slots,
                horizon_time=self.N * self.dt,
                hysteresis=cfg.neighbor_hysteresis,
            )
            evidence, shares = self._RobotShares(state, estimate, slots)
            robot = self._RobotTrajectory(q0, nu0, warm_start_inputs)
            if cfg.overtaking.enabled and robot is not None:
                behind = Overtaking(
                    slots.p0,
                    slots.v_pref,
                    slots.active,
                    robot.p[0],
                    robot.v[0],
                    cfg.overtaking,
                    kept=np.isin(slots.slot_ids, _Overtakers(state.last_prediction)),
                )
                shares = np.where(behind, cfg.overtaking.share, shares)
                if cfg.overtaking.wait:
                    slots.v_pref = np.where(behind[:, None], 0.0, slots.v_pref)
            self.orca.SetRobotShares(shares)
            if robot is not None:
                with PROFILER.Phase("predictor_forward_sim"):
                    positions, actions, multipliers = self.orca.ForwardSimulate(
                        slots, neighbors, robot
                    )
        guards = {}
        # React predicts nothing to contradict; CVMM's prediction already is
        # the guard's constant-velocity motion (a second, identical barrier
        # row would only double its penalty).
        if cfg.predictor == "orca_kkt":
            close = self._Close(estimate, distances, q0)
            guards = UpdateGuards(
                state.guard_steps,
                estimate,
                PredictedNow(last_solution, self.control_period, self.dt),
                deviation=self.guard_deviation,
                hold_steps=self.guard_hold_steps,
                close=close,
            )
            if not cfg.overtaking.guard:
                held = set(close) if cfg.overtaking.guard_close else set()
                for i in slots.slot_ids[behind]:
                    if int(i) not in held:
                        guards.pop(int(i), None)
        guarded = np.array([int(i) in guards for i in slots.slot_ids], dtype=bool)
        prediction = HumanPrediction(
            model=cfg.predictor,
            slot_ids=slots.slot_ids,
            active=slots.active,
            velocities=slots.v0,
            preferred_velocities=slots.v_pref,
            max_speeds=slots.max_speed,
            positions=positions,
            neighbors=neighbors,
            actions=actions,
            multipliers=multipliers,
            preferred_by_id=preferred,
            dropped=slots.dropped,
            extra_ids=slots.extra_ids,
            extra_positions=slots.extra_p0,
            extra_velocities=slots.extra_v0,
            guarded=guarded & slots.active,
            guard_steps_by_id=guards,
            estimate=estimate if estimate is not None else HumanEstimate(),
            robot_shares=shares,
            overtakers=behind & slots.active,
            share_evidence=evidence,
            robot_state=_RobotState(q0, nu0),
        )
        prediction.compute_time = time.perf_counter() - start
        return prediction, NextState(prediction)

    def _RobotShares(self, state, estimate, slots):
        """The evidence on each person's share of the avoidance toward the
        robot after this step, and each slot's share (reciprocity.py; the
        configured robot_share for everyone without the estimate)."""
        cfg = self.config
        r = cfg.reciprocity
        if not r.enabled:
            return {}, np.full(self.num_slots, cfg.robot_share)
        observations = ShareObservations(
            self.orca, state.last_prediction, estimate, r.min_difference, r.max_share
        )
        ids = () if estimate is None else estimate.ids
        evidence = UpdateEvidence(
            state.share_evidence, observations, ids, self._share_decay
        )
        shares = EstimatedShares(
            evidence, slots.slot_ids, cfg.robot_share, r.prior_weight
        )
        return evidence, shares

    def _Distances(self, estimate, q0):
        """Each estimate entry's distance from the robot's nearest body at
        q0 to the person's centre (inf where unknown), or None without
        people or a finite q0."""
        if estimate is None or q0 is None:
            return None
        q0 = np.asarray(q0, dtype=float)
        positions = np.asarray(estimate.positions, dtype=float).reshape(-1, 2)
        if not len(positions) or not np.all(np.isfinite(q0)):
            return None
        finite = np.all(np.isfinite(positions), axis=1)
        distances = np.full(len(positions), np.inf)
        if np.any(finite):
            distances[finite] = HumanDistances(
                self.robot, q0[None], positions[None, finite]
            )[0]
        return distances

    def _Close(self, estimate, distances, q0) -> list:
        """The ids of the people measured within guard_gap of the robot's
        nearest body (``distances``: _Distances; none with guard_gap 0 or
        without distances) and, with guard_approach > 0, walking toward it:
        their measured velocity, held for one control period, shrinks that
        gap faster than guard_approach (m/s)."""
        if self.guard_gap <= 0 or distances is None:
            return []
        close = (distances - self.human_radius) < self.guard_gap
        if self.guard_approach > 0 and np.any(close):
            delta = self.control_period
            moved = estimate.positions[close] + delta * estimate.velocities[close]
            after = np.full(len(moved), np.inf)
            finite = np.all(np.isfinite(moved), axis=1)
            if np.any(finite):
                q0 = np.asarray(q0, dtype=float)
                after[finite] = HumanDistances(
                    self.robot, q0[None], moved[None, finite]
                )[0]
            closing = (distances[close] - after) / delta > self.guard_approach
            close[np.flatnonzero(close)[~closing]] = False
        return [int(i) for i in np.asarray(estimate.ids)[close]]

    def _RobotTrajectory(self, q0, nu0, inputs):
        """The RobotView of the robot's warm start, or None."""
        state = _RobotState(q0, nu0)
        if state is None or inputs is None:
            return None
        q, nu, _ = Rollout(self.robot, *state, inputs, self.dt)
        return self.orca.RobotView(q[:-1], nu[:-1])


def _RobotState(q0, nu0):
    """(q, ν) as copies, or None if either is missing or not finite."""
    if q0 is None or nu0 is None:
        return None
    q, nu = np.array(q0, dtype=float), np.array(nu0, dtype=float)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(nu))):
        return None
    return q, nu


def _Overtakers(prediction):
    """The ids of the people the overtaking rule applied to in
    ``prediction`` (a HumanPrediction or None)."""
    if prediction is None or len(prediction.overtakers) == 0:
        return np.zeros(0, dtype=int)
    return np.asarray(prediction.slot_ids)[np.asarray(prediction.overtakers)]


def NextState(prediction: HumanPrediction) -> PredictorState:
    """What the predictor remembers after making ``prediction``."""
    return PredictorState(
        slot_ids=np.array(prediction.slot_ids),
        neighbors=np.array(prediction.neighbors),
        preferred_velocities=dict(prediction.preferred_by_id),
        guard_steps=dict(prediction.guard_steps_by_id),
        share_evidence=dict(prediction.share_evidence),
        last_prediction=prediction,
    )
