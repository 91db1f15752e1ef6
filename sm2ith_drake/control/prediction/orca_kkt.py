"""SM²ITH's interactive human prediction: the relaxed-ORCA QP of every human
at every step, embedded in the MPC through its KKT conditions (eq. smith).

For human j at step k (state: positions p_k, velocities v_k of everyone and
the robot base), the action a = a_{k,j} and slacks ζ = (ζ_a, ζ_v) solve

    min  ‖a − v_pref‖² + M_a ζ_a² + M_v ‖ζ_v‖²
    s.t. c_s = ‖a‖² − a_max² ≤ 0                          (speed)
         c_a = ‖a − v_k‖² − (Δt·acc_max)² − ζ_a ≤ 0         (acceleration)
         c_i = ρ_i − n_iᵀa − ζ_v,i ≤ 0                      (agent i's ORCA line)
         c_o = ρ_o − n_oᵀa ≤ 0                              (static obstacle lines)
         −ζ ≤ 0,

with (n, ρ) the ORCA half-planes as RVO2 builds them from the state (eq.
relaxed_orca_acc_argmin; the paper writes the acceleration slack as
tightening the constraint, but a slack that keeps the QP feasible must
relax it, as here). Its KKT conditions (eqs. smith_kkt_*) are

    stationarity in a:  2(a − v_pref) + 2λ_s a + 2λ_a (a − v_k)
                        − Σ λ_i n_i − Σ λ_o n_o = 0,
    stationarity in ζ:  2M_a ζ_a − λ_a − μ_a = 0,  2M_v ζ_v,i − λ_i − μ_i = 0,
    primal c ≤ 0, ζ ≥ 0;  dual λ, μ ≥ 0;  complementarity λ·c = 0, μ·ζ = 0.

The slack block is solved exactly and eliminated: if ζ > 0 then μ = 0 and
λ = 2Mζ; if ζ = 0 then λ + μ = 0 with λ, μ ≥ 0, so λ = μ = 0 = 2Mζ. Hence
μ ≡ 0 and ζ = λ/(2M) at every KKT point, and the system is equivalent to

    stationarity in a (above),
    c_s ≤ 0,  ‖a − v_k‖² − (Δt·acc_max)² − λ_a/(2M_a) ≤ 0,
    ρ_i − n_iᵀa − λ_i/(2M_v) ≤ 0,  c_o ≤ 0,   λ ≥ 0,   λ·c = 0,

in a and λ only (4 + A + S variables per human and step instead of
6 + 3A + S). The MPC carries a and λ as decision variables, with the human
dynamics p_{k+1} = p_k + Δt a_k, v_{k+1} = a_k. Exact complementarity
violates the usual constraint qualifications; it is relaxed to λ·c ≥ −ε with
ε = ``complementarity_relaxation`` (chosen by measurement, see scenario.py).

Agents (orca_model.py). As RVO2 (``maxNeighbors``), each human reacts to at most
``max_neighbors`` other humans: the ones that come closest within the
horizon at constant velocity, chosen once per control step (an incumbent is
only replaced by someone closer by ``neighbor_hysteresis``); with
max_neighbors ≥ H − 1 every pair interacts. This keeps the problem's size
linear in the number of people. Every human also reacts to the robot as the
simulated people see it (humans/crowd.py): its base, and its body nearest
to the human (the closest point on the nearest capsule's axis, moving with
the base), so an outstretched arm is avoided too.

The half-planes depend on the predicted states, so the robot's plan moves
the predicted humans: that is the interaction. Their Jacobians w.r.t. the
states are taken by central differences of the vectorized ORCA agent lines
of humans/orca.py, the same geometry the reference uses (piecewise smooth),
and the chain rule through the nearest body's point (NearestBodies).

Jacobian. With ``neighbor_derivatives`` the KKT Jacobian is exact and its
sparsity pattern changes with the neighbour sets (``pattern_key``; the RTI
solver keeps a QP workspace per pattern). By default it is block-Jacobi:
each human's block is differentiated only w.r.t. its own and the robot's
states, while the lines are still evaluated at the other humans' current
predictions, so every human's block couples to the robot only (a sparse
factorization linear in the number of people) and a converged plan still
satisfies the coupled KKT system.
"""

import numpy as np

from sm2ith_drake.control.groups import INPUT
from sm2ith_drake.control.prediction.base import Predictor
from sm2ith_drake.control.prediction.kkt_groups import (
    KktBlocks,
    KktEqualities,
    KktInequalities,
    KktTerms,
)
from sm2ith_drake.control.prediction.orca_model import OrcaModel
from sm2ith_drake.control.prediction.slots import DefaultNeighbors
from sm2ith_drake.control.profiling import PROFILER
from sm2ith_drake.humans.messages import HumanPrediction


class OrcaKkt(Predictor):
    """The KKT embedding of every human's relaxed-ORCA QP (module doc)."""

    name = "orca_kkt"

    def __init__(
        self, config, *, horizon, time_step, robot, obstacles=(), human_radius=0.3
    ):
        super().__init__(config, horizon=horizon, time_step=time_step)
        self.robot = robot
        self.model = OrcaModel(
            config,
            horizon=horizon,
            time_step=time_step,
            robot=robot,
            obstacles=obstacles,
            human_radius=human_radius,
        )
        m = self.model
        self.num_neighbors = m.num_neighbors
        self.num_agent_lines = m.num_agent_lines
        self.num_static_lines = m.num_static_lines
        self.num_multipliers = m.num_multipliers
        # The steps with KKT rows; later ones hold the last action.
        self.kkt_steps = m.kkt_steps
        # neighbors[j]: the slots whose lines slot j has (from the prediction).
        self.neighbors = DefaultNeighbors(self.num_slots, self.num_neighbors)
        self._warm_start = None
        self._blocks = None

    @property
    def pattern_key(self) -> bytes:
        """Changes exactly when the Jacobian sparsity pattern does."""
        if not self.config.neighbor_derivatives:
            return b""
        return self.neighbors.tobytes()

    # -------------------------------------------------------------- variables

    def AddVariables(self, layout):
        super().AddVariables(layout)
        N, H = self.N, self.num_slots
        self.a = layout.AddVariables("human_a", (N, H, 2), role=INPUT)
        self.lam = layout.AddVariables(
            "human_lambda", (N, H, self.num_multipliers), role=INPUT
        )

    def MultiplierVariables(self):
        """The multipliers λ of every person's relaxed-ORCA QP."""
        return self.lam.ravel()

    def ConstraintGroups(self, program):
        self._blocks = KktBlocks(self, program.layout)
        self._equality = KktEqualities(self, self._blocks)
        self._inequality = KktInequalities(self, self._blocks)
        eps = self.config.complementarity_relaxation
        lo, hi = self._inequality.Bounds(eps)
        m = self._equality.num_rows
        return [(self._equality, np.zeros(m), np.zeros(m)), (self._inequality, lo, hi)]

    def ApplyBounds(self, lower, upper):
        """The people's initial positions (eq. smith_init) and dual
        feasibility λ ≥ 0 (eq. smith_kkt_dual).

        An empty slot is a person parked far away at rest (slots.py), whose
        own relaxed-ORCA QP is solved by a = 0 with every constraint
        inactive, whatever the robot's plan: its positions, actions and
        multipliers are pinned there (the values the forward simulation
        gives them), so the QP does not carry them as free variables.
        Measured: with 1 person in 3 slots HPIPM's IPM stalled on 93 % of
        the stage QPs with them free (min_step), and solved every one with
        them pinned."""
        lower[self.p[0]] = upper[self.p[0]] = self.p0
        lower[self.lam] = 0.0
        # Past kkt_steps a person holds its last action: no QP, no λ.
        upper[self.lam[self.kkt_steps :]] = 0.0
        empty = ~self.active
        if empty.any():
            parked = np.broadcast_to(self.p0[empty], self.p[1:, empty].shape)
            lower[self.p[1:, empty]] = upper[self.p[1:, empty]] = parked
            lower[self.a[:, empty]] = upper[self.a[:, empty]] = 0.0
            lower[self.lam[:, empty]] = upper[self.lam[:, empty]] = 0.0

    def SetPrediction(self, prediction: HumanPrediction) -> None:
        super().SetPrediction(prediction)
        self._warm_start = prediction
        # The shares the prediction was made with (None: robot_share).
        self.model.SetRobotShares(prediction.robot_shares)
        neighbors = np.asarray(prediction.neighbors, dtype=int).reshape(
            self.num_slots, self.num_neighbors
        )
        if not np.array_equal(neighbors, self.neighbors):
            self.neighbors = neighbors
            if self._blocks is not None:
                self._blocks.UpdatePattern()

    # ---------------------------------------------------------------- model

    def HumanVelocities(self, z):
        """v_k of every human for k = 0 … N−1: (N, H, 2)."""
        a = z[self.a]
        return np.concatenate([self.v0[None], a[:-1]], axis=0)

    def RobotViewOf(self, z, layout, kin=None, steps=None):
        """The RobotView of z's robot plan, steps 0 … ``steps``−1 (None:
        N−1)."""
        T = self.N if steps is None else steps
        return self.model.RobotView(z[layout.q[:T]], z[layout.nu[:T]], kin)

    def HalfPlanes(self, positions, velocities, robot):
        """OrcaModel.HalfPlanes with this step's neighbour sets."""
        return self.model.HalfPlanes(positions, velocities, robot, self.neighbors)

    def HalfPlaneDerivatives(self, p, v, robot, h=1e-6):
        """OrcaModel.HalfPlaneDerivatives with this step's neighbour sets."""
        return self.model.HalfPlaneDerivatives(p, v, robot, self.neighbors, h)

    def LocalState(self, z, layout, kin=None):
        """The states the k-th QPs depend on, k = 0 … T−1 (T =
        kkt_steps): human positions and velocities (T, H, 2) and the
        RobotView (``kin``: see OrcaModel.RobotView)."""
        T = self.kkt_steps
        p = z[self.p[:T]]
        v = self.HumanVelocities(z)[:T]
        return p, v, self.RobotViewOf(z, layout, kin, steps=T)

    def Residuals(self, z, layout):
        """KKT residuals at z (for diagnostics and tests) over the T =
        kkt_steps steps: stationarity (T, H, 2), primal c (T, H, R) and
        complementarity λ·c (T, H, R), with the slacks eliminated (ζ = λ/2M,
        module doc)."""
        p, v, robot = self.LocalState(z, layout)
        n, rho, no, rho_o = self.HalfPlanes(p, v, robot)
        return KktTerms(self, z, v, n, rho, no, rho_o)

    def WarmStart(self, z):
        """Human variables of the guess z: the HumanPredictor's forward
        simulation of each human's relaxed-ORCA QP along the robot's warm
        start (positions, actions and multipliers: an exact KKT point to
        linearize at). Without one (no robot trajectory to simulate
        against), the humans are simulated here along z's robot plan."""
        prediction = self._warm_start
        if prediction is None or prediction.actions is None:
            z[self.p[0]] = self.p0
            self.Restore(z)
            return
        z[self.p] = prediction.positions
        z[self.a] = prediction.actions
        z[self.lam] = prediction.multipliers

    def PredictionErrors(self, z):
        """PredictionConsistency of plan z, flattened."""
        return PredictionConsistency(self, z, self.layout).ravel()

    def Restore(self, z):
        """The humans' exact relaxed-ORCA responses to z's robot plan, so the
        next SQP pass linearizes the KKT system at a point that satisfies it
        (a pass linearized at the previous QP's inexact KKT point was primal
        infeasible in a quarter of the steps with five people)."""
        with PROFILER.Phase("restore_forward_sim"):
            p, a, lam = self.model.ForwardSimulate(
                self, self.neighbors, self.RobotViewOf(z, self.layout), p0=z[self.p[0]]
            )
        z[self.p] = p
        z[self.a] = a
        z[self.lam] = lam


def PredictionConsistency(predictor, z, layout) -> np.ndarray:
    """The honest check of the KKT embedding: re-solve every active human's
    relaxed-ORCA QP at the predicted states of plan z and return
    ‖a_QP − a_predicted‖ for every (k, j) (m/s), shape (T, active) over the
    T = kkt_steps steps that embed the QP."""
    with PROFILER.Phase("prediction_check"):
        return _PredictionConsistency(predictor, z, layout)


def _PredictionConsistency(predictor, z, layout):
    p, v, robot = predictor.LocalState(z, layout)
    n, rho, no, rho_o = predictor.HalfPlanes(p, v, robot)
    N = predictor.kkt_steps
    a = z[predictor.a[:N]]
    active = np.nonzero(predictor.active)[0]
    B = len(active)
    A, S = predictor.num_agent_lines, predictor.num_static_lines
    sol = predictor.model.SolveHumanQps(
        predictor.v_pref[np.tile(active, N)],
        v[:, active].reshape(N * B, 2),
        n[:, active].reshape(N * B, A, 2),
        rho[:, active].reshape(N * B, A),
        no[:, active].reshape(N * B, S, 2),
        rho_o[:, active].reshape(N * B, S),
        predictor.max_speed[np.tile(active, N)],
    )
    return np.linalg.norm(sol.velocity.reshape(N, B, 2) - a[:, active], axis=-1)
