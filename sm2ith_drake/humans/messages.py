"""The messages that flow between the systems: what motion capture sees
(HumanDetections), the tracked people (HumanEstimate) and the controller's
plan (MpcPlan). Plain dataclasses: no Drake, no math.
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass
class HumanDetections:
    """One motion-capture frame: the ids seen and their measured positions."""

    time: float = 0.0
    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass
class HumanEstimate:
    """The tracked humans at one instant (from the estimator or the truth)."""

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    # Known preferred velocities (intents), NaN where unknown. Only the
    # simulation's ground truth knows them, for people who walk as the
    # prediction model says (crowd behaviour "relaxed_orca"); None: unknown.
    preferred_velocities: np.ndarray | None = None

    def __post_init__(self):
        self.ids = np.asarray(self.ids, dtype=int).reshape(-1)
        self.positions = np.asarray(self.positions, dtype=float).reshape(-1, 2)
        self.velocities = np.asarray(self.velocities, dtype=float).reshape(-1, 2)
        if self.preferred_velocities is not None:
            self.preferred_velocities = np.asarray(
                self.preferred_velocities, dtype=float
            ).reshape(-1, 2)
        lengths = {len(self.ids), len(self.positions), len(self.velocities)}
        if self.preferred_velocities is not None:
            lengths.add(len(self.preferred_velocities))
        if len(lengths) != 1:
            raise ValueError(
                "HumanEstimate: ids, positions, velocities differ in length"
            )


@dataclass
class MpcPlan:
    """The ``plan`` output: the latest MpcSolution, or None before the first
    successful solve."""

    solution: object = None
