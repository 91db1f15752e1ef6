"""The messages that flow between the systems: what motion capture sees
(HumanDetections), the people's states (HumanEstimate, from the estimator or
the simulation's truth), the intents only a simulation knows (HumanIntents),
the predictor's output (HumanPrediction) and the controller's plan (MpcPlan).
Plain dataclasses: no Drake, no math.
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass
class HumanDetections:
    """One motion-capture frame: the ids seen and their measured positions."""

    time: float = 0.0
    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def _Rows(values, dtype=float, width=2) -> np.ndarray:
    return np.asarray(values, dtype=dtype).reshape(-1, width)


@dataclass
class HumanEstimate:
    """The people's positions and velocities at one instant, by id: the
    estimator's tracks, or the simulation's ground truth (``human_truth``)."""

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def __post_init__(self):
        self.ids = np.asarray(self.ids, dtype=int).reshape(-1)
        self.positions = _Rows(self.positions)
        self.velocities = _Rows(self.velocities)
        if not len(self.ids) == len(self.positions) == len(self.velocities):
            raise ValueError(
                "HumanEstimate: ids, positions, velocities differ in length"
            )


@dataclass
class HumanIntents:
    """The preferred velocities (intents) of simulated people, by id; NaN
    where unknown. Only the simulation knows them, for the people who walk
    as the prediction model says (crowd behaviour ``relaxed_orca``); they
    reach the predictor through its simulation-only ``human_intents`` input
    (ideal perception of intent), never on hardware."""

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    preferred_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def __post_init__(self):
        self.ids = np.asarray(self.ids, dtype=int).reshape(-1)
        self.preferred_velocities = _Rows(self.preferred_velocities)
        if len(self.ids) != len(self.preferred_velocities):
            raise ValueError("HumanIntents: ids and velocities differ in length")


@dataclass
class HumanPrediction:
    """The HumanPredictor's output: the people in the MPC's fixed slots and
    their predicted motion over the horizon.

    ``positions`` (N+1, H, 2) are the predicted trajectories under the
    predictor's model (ORCA forward-simulated against the robot's warm-start
    plan, constant velocity, or held). With the ORCA model, ``actions``
    (N, H, 2) and ``multipliers`` (N, H, R) are the forward simulation's
    relaxed-ORCA solutions: the warm start that the KKT embedding refines
    jointly with the robot's plan, and ``neighbors`` (H, K) its structure.
    """

    model: str = "react"
    # Human id per slot (−1: empty) and whether the slot holds a person.
    slot_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    active: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    # Measured (estimated) velocities and the model's preferred velocities.
    velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    preferred_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    # The model's speed limit of each slot's person (H,) (empty: the
    # configured max_speed for everyone; PredictionConfig.max_speed_factor).
    max_speeds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((1, 0, 2)))
    neighbors: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=int))
    actions: np.ndarray | None = None
    multipliers: np.ndarray | None = None
    # The preferred velocity of every tracked person, by id (also those
    # without a slot); the predictor remembers it for the next step.
    preferred_by_id: dict = field(default_factory=dict)
    # People tracked but not seen by the controller: neither a slot nor an
    # extra (more than max_humans + max_extra_humans).
    dropped: int = 0
    # People without a slot whom the DT-CBF keeps out of at constant
    # velocity (PredictionConfig.max_extra_humans): id (−1: none), measured
    # position and velocity, (E,), (E, 2), (E, 2).
    extra_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    extra_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    extra_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    # Slots whose person the MPC's guard holds (SafetyConfig.guard_deviation)
    # and, by id, for how many more control steps (remembered).
    guarded: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    guard_steps_by_id: dict = field(default_factory=dict)
    # The estimate the prediction was made from (every tracked person).
    estimate: HumanEstimate = field(default_factory=HumanEstimate)
    # The ORCA model's share of the avoidance toward the robot per slot (H,)
    # (PredictionConfig.robot_share, or its online estimate), None for the
    # other models; the evidence for the estimate by id ((Σ w·s, Σ w),
    # remembered) and the robot's (q, ν) the prediction was made at.
    robot_shares: np.ndarray | None = None
    # Slots whose person the overtaking rule applies to (H,) (remembered:
    # PredictionConfig.overtaking.keep_angle).
    overtakers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    share_evidence: dict = field(default_factory=dict)
    robot_state: tuple | None = None
    # Wall time spent making this prediction (s): part of the control step's
    # time (the controller adds it to its StepRecord and its time budget).
    compute_time: float = 0.0

    def ExtraVelocities(self) -> np.ndarray:
        """(E, 2) the velocities the controller's barrier assumes the extras
        move on at: the measured ones, or zero for React, which holds
        everyone where measured."""
        v = np.asarray(self.extra_velocities, dtype=float).reshape(-1, 2)
        return np.zeros_like(v) if self.model == "react" else v


@dataclass
class MpcPlan:
    """The controller's ``plan`` output.

    ``solution`` is the latest solve attempt (an MpcSolution, successful or
    not; None before the first step), for visualization and diagnostics.
    ``warm_start_inputs`` (N, m) are the inputs the next control step starts
    from: the last successful plan's, shifted by the steps since it was
    solved (zeros where it has none); the predictor rolls them out to predict
    the people's responses to the robot's warm start.
    """

    solution: object = None
    warm_start_inputs: np.ndarray | None = None
