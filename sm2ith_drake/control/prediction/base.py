"""Human motion predictors behind one interface that plugs into the MPC.

Every predictor owns the human positions p_{k,j} (k = 0 … N, j = 1 … H) as
decision variables of the MPC program; the DT-CBF constraints read them.
Each control step the predictor is handed the HumanPredictor system's output
(a HumanPrediction: the people in their slots and their predicted motion),
which overwrites everything it uses in that step; it keeps nothing between
steps (that lives in the HumanPredictor's Context, control/prediction/slots.py).

- :class:`React`: p_{k,j} = p_{0,j} (held at the current position);
- :class:`Cvmm`: p_{k,j} = p_{0,j} + kΔt v_{0,j} (constant velocity);
  both fixed by variable bounds before each solve;
- :class:`~sm2ith_drake.control.prediction.orca_kkt.OrcaKkt`: SM²ITH's
  interactive model, refined jointly with the robot's plan.
"""

import numpy as np

from sm2ith_drake.control.groups import STATE
from sm2ith_drake.control.prediction.slots import ParkedPositions
from sm2ith_drake.humans.messages import HumanPrediction


def HeldPrediction(p0: np.ndarray, horizon: int) -> np.ndarray:
    """React's "prediction": everyone stays where they are, (N+1, H, 2)."""
    return np.broadcast_to(p0, (horizon + 1,) + p0.shape).copy()


def ConstantVelocityPrediction(
    p0: np.ndarray, v0: np.ndarray, horizon: int, time_step: float
) -> np.ndarray:
    """CVMM: everyone keeps their velocity, (N+1, H, 2)."""
    k = np.arange(horizon + 1)[:, None, None] * time_step
    return p0[None] + k * v0[None]


def PredictionMaxSpeeds(prediction: HumanPrediction, default: float) -> np.ndarray:
    """(H,) the model's speed limit of each slot: the prediction's own
    (``max_speeds``) or ``default`` for every slot where it has none."""
    H = len(prediction.slot_ids)
    speeds = np.asarray(prediction.max_speeds, dtype=float).reshape(-1)
    return speeds.copy() if speeds.size == H else np.full(H, float(default))


class Predictor:
    """The common part: the position variables, pinned to the prediction."""

    name = "react"

    def __init__(self, config, *, horizon: int, time_step: float):
        self.config = config
        self.N = horizon
        self.dt = time_step
        self.num_slots = H = int(config.max_humans)
        # This step's people (SetPrediction overwrites them every step).
        self.slot_ids = np.full(H, -1)
        self.active = np.zeros(H, dtype=bool)
        self.p0 = ParkedPositions(H)
        self.v0 = np.zeros((H, 2))
        self.v_pref = np.zeros((H, 2))
        self.max_speed = np.full(H, float(config.max_speed))
        self.guarded = np.zeros(H, dtype=bool)
        self.positions = HeldPrediction(self.p0, horizon)
        # The people without a slot that the barrier keeps out of.
        E = int(config.max_extra_humans)
        self.extra_active = np.zeros(E, dtype=bool)
        self.extra_p0 = np.zeros((E, 2))
        self.extra_v0 = np.zeros((E, 2))

    def AddVariables(self, layout) -> None:
        self.layout = layout
        self.p = layout.AddVariables(
            "human_p", (self.N + 1, self.num_slots, 2), role=STATE
        )

    def ConstraintGroups(self, program) -> list:
        return []

    def SetPrediction(self, prediction: HumanPrediction) -> None:
        """Takes this control step's people and their predicted motion."""
        self.slot_ids = np.array(prediction.slot_ids, dtype=int)
        self.active = np.array(prediction.active, dtype=bool)
        self.positions = np.asarray(prediction.positions, dtype=float)
        self.p0 = self.positions[0]
        self.v0 = np.asarray(prediction.velocities, dtype=float)
        self.v_pref = np.asarray(prediction.preferred_velocities, dtype=float)
        self.max_speed = PredictionMaxSpeeds(prediction, self.config.max_speed)
        guarded = np.asarray(prediction.guarded, dtype=bool)
        self.guarded = guarded if guarded.shape == self.active.shape else self.active
        E = self.extra_active.size
        ids = np.asarray(prediction.extra_ids, dtype=int).reshape(-1)
        if ids.size != E:  # a prediction without (these) extras: none
            ids = np.full(E, -1)
        self.extra_active = ids >= 0
        self.extra_p0 = np.zeros((E, 2))
        self.extra_v0 = np.zeros((E, 2))
        if self.extra_active.any():
            self.extra_p0 = np.asarray(prediction.extra_positions, dtype=float)
            # Moving on at their measured velocity; React holds everyone.
            self.extra_v0 = prediction.ExtraVelocities()

    def ApplyBounds(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """Pins the predicted positions (React, CVMM) — in place."""
        lower[self.p] = self.positions
        upper[self.p] = self.positions

    def WarmStart(self, z: np.ndarray) -> None:
        """Fills the human variables of the initial guess z (in place)."""
        z[self.p] = self.positions

    def Restore(self, z: np.ndarray) -> None:
        """Makes the human variables of z consistent with its robot plan
        before another SQP pass linearizes at z (in place). The fixed
        predictions of React and CVMM are already."""

    def MultiplierVariables(self) -> np.ndarray:
        """Indices of the predictor's dual variables (none for React and
        CVMM)."""
        return np.zeros(0, dtype=int)

    def Predictions(self, z: np.ndarray) -> np.ndarray:
        return z[self.p].copy()

    def PredictionErrors(self, z: np.ndarray) -> np.ndarray:
        """How far plan z's predicted human actions are from what the
        people's model does at z's states (m/s, one per step and active
        person). Empty for React and CVMM: their predictions are fixed."""
        return np.zeros(0)


class React(Predictor):
    """Humans held at their current positions (no prediction)."""

    name = "react"


class Cvmm(Predictor):
    """Constant-velocity predictions, fixed before each solve."""

    name = "cvmm"
