"""Human motion predictors behind one interface that plugs into the MPC.

Every predictor owns the human positions p_{k,j} (k = 0 … N, j = 1 … H) as
decision variables of the MPC program; the DT-CBF constraints read them.
The program has a fixed number H of human slots (``max_humans``); tracked
humans are assigned to slots by id and kept there while they are tracked,
so warm starts stay aligned. Empty slots are parked far away, where no
constraint is active.

- :class:`React`: p_{k,j} = p_{0,j} (held at the current position);
- :class:`Cvmm`: p_{k,j} = p_{0,j} + kΔt v_{0,j} (constant velocity);
  both fixed by variable bounds before each solve;
- :class:`OrcaKkt` (``humans/orca_kkt.py``): SM²ITH's interactive model.
"""

import numpy as np

from sm2ith_drake.humans.messages import HumanEstimate

# Where empty human slots are parked (m): far from anything, finite.
PARKED = np.array([1.0e3, 1.0e3])


class Predictor:
    """The common part: slots, the position variables, and React's model."""

    name = "react"

    def __init__(self, config, *, horizon: int, time_step: float):
        self.config = config
        self.N = horizon
        self.dt = time_step
        self.H = int(config.max_humans)
        self._slot_ids = np.full(self.H, -1)  # id per slot, −1 = empty
        self.p0 = np.tile(PARKED, (self.H, 1)) + 10.0 * np.arange(self.H)[:, None]
        self.v0 = np.zeros((self.H, 2))
        self.v_pref = np.zeros((self.H, 2))  # the ORCA model's v_pref
        self.active = np.zeros(self.H, dtype=bool)
        self.dropped = 0  # humans beyond H that could not get a slot

    def AddVariables(self, layout) -> None:
        self.layout = layout
        self.p = layout.AddVariables("human_p", (self.N + 1, self.H, 2))

    def ConstraintGroups(self, program) -> list:
        return []

    def SetHumans(
        self,
        estimate: HumanEstimate | None,
        preferred_velocities: np.ndarray | None = None,
    ) -> None:
        """Assigns the tracked humans to slots (stable by id).

        ``preferred_velocities`` (rows as the estimate's; default: the
        measured velocities) are the v_pref of the ORCA model."""
        estimate = estimate or HumanEstimate()
        if preferred_velocities is None:
            preferred_velocities = estimate.velocities
        preferred_velocities = np.asarray(preferred_velocities, float).reshape(-1, 2)
        ok = (
            np.all(np.isfinite(estimate.positions), axis=1)
            & np.all(np.isfinite(estimate.velocities), axis=1)
            & np.all(np.isfinite(preferred_velocities), axis=1)
        )
        ids = estimate.ids[ok]
        pos, vel = estimate.positions[ok], estimate.velocities[ok]
        pref = preferred_velocities[ok]
        keep = np.isin(self._slot_ids, ids)
        self._slot_ids[~keep] = -1
        self.dropped = 0
        for i, hid in enumerate(ids):
            slots = np.nonzero(self._slot_ids == hid)[0]
            if not slots.size:
                free = np.nonzero(self._slot_ids < 0)[0]
                if not free.size:
                    self.dropped += 1
                    continue
                self._slot_ids[free[0]] = hid
                slots = free[:1]
            self.p0[slots[0]] = pos[i]
            self.v0[slots[0]] = vel[i]
            self.v_pref[slots[0]] = pref[i]
        self.active = self._slot_ids >= 0
        parked = np.tile(PARKED, (self.H, 1)) + 10.0 * np.arange(self.H)[:, None]
        self.p0[~self.active] = parked[~self.active]
        self.v0[~self.active] = 0.0
        self.v_pref[~self.active] = 0.0

    @property
    def slot_ids(self) -> np.ndarray:
        return self._slot_ids.copy()

    def Model(self) -> np.ndarray:
        """The fixed prediction (N+1, H, 2) of React / CVMM."""
        return np.broadcast_to(self.p0, (self.N + 1, self.H, 2)).copy()

    def ApplyBounds(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """Pins the predicted positions (React, CVMM) — in place."""
        model = self.Model()
        lower[self.p] = model
        upper[self.p] = model

    def WarmStart(self, z: np.ndarray, previous=None, shift: int = 1) -> None:
        """Fills the human variables of the initial guess z (in place)."""
        z[self.p] = self.Model()

    def Restore(self, z: np.ndarray) -> None:
        """Makes the human variables of z consistent with its robot plan
        before another SQP pass linearizes at z (in place). The fixed
        predictions of React and CVMM are already."""

    def Predictions(self, z: np.ndarray) -> np.ndarray:
        return z[self.p].copy()


class React(Predictor):
    """Humans held at their current positions (no prediction)."""

    name = "react"


class Cvmm(Predictor):
    """Constant-velocity predictions, fixed before each solve."""

    name = "cvmm"

    def Model(self) -> np.ndarray:
        k = np.arange(self.N + 1)[:, None, None] * self.dt
        return self.p0[None] + k * self.v0[None]
