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

Agents. As RVO2 (``maxNeighbors``), each human reacts to at most
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

from sm2ith_drake.control.prediction.base import Predictor
from sm2ith_drake.control.prediction.kkt_groups import (
    KktBlocks,
    KktEqualities,
    KktInequalities,
    KktTerms,
)
from sm2ith_drake.humans.half_planes import obstacle_half_planes, orca_agent_half_planes
from sm2ith_drake.humans.relaxed_orca import relaxed_orca_actions
from sm2ith_drake.humans.robot_view import NearestBodies, RobotView

_EPS = 1e-9


class OrcaKkt(Predictor):
    """The KKT embedding of every human's relaxed-ORCA QP (module doc)."""

    name = "orca_kkt"

    def __init__(
        self, config, *, horizon, time_step, robot, obstacles=(), human_radius=0.3
    ):
        super().__init__(config, horizon=horizon, time_step=time_step)
        self.robot = robot
        self.segments = np.asarray(obstacles, dtype=float).reshape(-1, 2, 2)
        # The radius the people are modelled with (SafetyConfig.human_radius).
        self.human_radius = float(human_radius)
        self.robot_radius = robot.model.base_radius
        H = self.H
        # Human neighbours per human (RVO2's maxNeighbors), then the robot's
        # base and its body nearest to the person.
        self.K = max(0, min(int(config.max_neighbors), H - 1))
        self.A = self.K + 2  # agent lines per human
        self.S = len(self.segments)
        self.R = 2 + self.A + self.S  # constraints (multipliers) per human
        # neighbors[j]: the humans whose lines human j has (sorted indices).
        self.neighbors = np.array(
            [[i for i in range(H) if i != j][: self.K] for j in range(H)], dtype=int
        ).reshape(H, self.K)
        # Combined radii (the nearest body's is set per person and step).
        self._radius = np.full(self.A, 2 * self.human_radius)
        self._radius[self.K] = self.human_radius + self.robot_radius
        self._share = np.full(self.A, 0.5)
        self._share[self.K :] = config.robot_share
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
        N, H = self.N, self.H
        self.a = layout.AddVariables("human_a", (N, H, 2))
        self.lam = layout.AddVariables("human_lambda", (N, H, self.R))

    def ConstraintGroups(self, program):
        self._blocks = KktBlocks(self, program.layout)
        self._equality = KktEqualities(self, self._blocks)
        self._inequality = KktInequalities(self, self._blocks)
        eps = self.config.complementarity_relaxation
        lo, hi = self._inequality.Bounds(eps)
        m = self._equality.num_rows
        return [(self._equality, np.zeros(m), np.zeros(m)), (self._inequality, lo, hi)]

    def ApplyBounds(self, lower, upper):
        lower[self.p[0]] = upper[self.p[0]] = self.p0
        lower[self.lam] = 0.0

    def SetHumans(self, estimate, preferred_velocities=None):
        super().SetHumans(estimate, preferred_velocities)
        neighbors = self.SelectNeighbors()
        if not np.array_equal(neighbors, self.neighbors):
            self.neighbors = neighbors
            if self._blocks is not None:
                self._blocks.UpdatePattern()

    def SelectNeighbors(self) -> np.ndarray:
        """Each human's K neighbours: the humans that come closest to it
        within the horizon if everyone keeps their velocity (active humans
        before empty slots), incumbents favoured by ``neighbor_hysteresis``
        so the sets (and the QP's pattern) do not flicker."""
        H, K = self.H, self.K
        if K == 0:
            return np.zeros((H, 0), dtype=int)
        if K == H - 1:
            return self.neighbors
        r = self.p0[None, :] - self.p0[:, None]  # (H, H, 2): i relative to j
        w = self.v0[None, :] - self.v0[:, None]
        horizon = self.N * self.dt
        t = np.clip(
            -np.sum(r * w, axis=-1) / np.maximum(np.sum(w * w, axis=-1), _EPS),
            0.0,
            horizon,
        )
        d = np.linalg.norm(r + t[..., None] * w, axis=-1)
        d[:, ~self.active] += 1e6  # empty slots only as fillers
        np.fill_diagonal(d, np.inf)
        rows = np.arange(H)[:, None]
        d[rows, self.neighbors] -= self.config.neighbor_hysteresis
        chosen = np.argsort(d, axis=1, kind="stable")[:, :K]
        return np.sort(chosen, axis=1)

    # ---------------------------------------------------------------- model

    def _HumanVelocities(self, z):
        """v_k of every human for k = 0 … N−1: (N, H, 2)."""
        a = z[self.a]
        return np.concatenate([self.v0[None], a[:-1]], axis=0)

    def RobotView(self, q, nu, kin=None) -> "RobotView":
        """The robot as the people see it at the configurations q (T, n) and
        velocities ν (T, m): its base, and its bodies for the nearest-body
        agent (see _AgentStates). ``kin``: the kinematics of configurations
        whose first T rows are q, if the caller has them already."""
        robot = self.robot
        G = np.stack([robot.G(qk) for qk in q])  # (T, n, m)
        if kin is None:
            kin = robot.CalcKinematics(q)
        T = len(q)
        return RobotView(
            q=q,
            nu=nu,
            p=q[:, :2],
            v=np.einsum("knm,km->kn", G[:, :2], nu),
            ends=kin.capsule_points[:T, ..., :2],
            ends_jacobian=kin.capsule_jacobians[:T, ..., :2, :],
            radii=robot.capsule_radii,
        )

    def _RobotView(self, z, layout, kin=None):
        return self.RobotView(z[layout.q[:-1]], z[layout.nu[:-1]], kin)

    def _AgentStates(self, positions, velocities, robot):
        """Each line's own and other agent's states, (T, H, A, 2) each (own
        p, own v, other p, other v), the combined radii (T, H, A) and the
        nearest robot bodies. The lines are the K neighbours', the robot
        base's, and the robot's nearest body's: as the simulated people see
        the robot (humans/crowd.py), the closest point on the axis of the
        capsule nearest to the person, moving with the base, so an arm
        sticking out is avoided too."""
        T, H, A = positions.shape[0], self.H, self.A
        shape = (T, H, A, 2)
        body = NearestBodies(robot, positions)
        robot_p = np.broadcast_to(robot.p[:, None, None], (T, H, 1, 2))
        robot_v = np.broadcast_to(robot.v[:, None, None], (T, H, 2, 2))
        nb = self.neighbors
        radius = np.empty((T, H, A))
        radius[:] = self._radius
        radius[..., -1] = self.human_radius + body.radius
        states = (
            np.broadcast_to(positions[:, :, None], shape),
            np.broadcast_to(velocities[:, :, None], shape),
            np.concatenate([positions[:, nb], robot_p, body.point[:, :, None]], axis=2),
            np.concatenate([velocities[:, nb], robot_v], axis=2),
        )
        return states, radius, body

    def _AgentLines(self, own_p, own_v, other_p, other_v, radius):
        return orca_agent_half_planes(
            own_p,
            own_v,
            other_p,
            other_v,
            radius,
            self._share,
            tau=self.config.tau,
            time_step=self.dt,
        )

    def _StaticLines(self, positions):
        if self.S:
            return obstacle_half_planes(
                positions, self.segments, self.human_radius, tau_obs=self.config.tau_obs
            )
        T, H = positions.shape[:2]
        return np.zeros((T, H, 0, 2)), np.zeros((T, H, 0))

    def HalfPlanes(self, positions, velocities, robot):
        """Agent lines (n (T, H, A, 2), ρ (T, H, A)) and static lines
        (n (T, H, S, 2), ρ (T, H, S)) for human states of shape (T, H, 2)
        and the RobotView of the same T steps."""
        states, radius, _ = self._AgentStates(positions, velocities, robot)
        n, rho = self._AgentLines(*states, radius)
        return (n, rho) + self._StaticLines(positions)

    def LocalState(self, z, layout):
        """The states the k-th QPs depend on, k = 0 … N−1: human positions
        and velocities (N, H, 2) and the RobotView."""
        p = z[self.p[:-1]]
        v = self._HumanVelocities(z)
        return p, v, self._RobotView(z, layout)

    def HalfPlaneDerivatives(self, p, v, robot, h=1e-6):
        """Half-planes and their central-difference derivatives.

        Each agent line depends on its own human's state and on one other
        agent's, so all lines are differenced at once in those 8 inputs:
        dn (T, H, A, 2, 8), dρ (T, H, A, 8), in the order own p, own v,
        other p, other v (the nearest body's point is an input here; its
        own dependence on the configuration and the person's position is
        applied by the chain rule in KktBlocks). Static lines depend on the
        own position only: dn_o (T, H, S, 2, 2), dρ_o (T, H, S, 2). Also
        returns the NearestBodies."""
        states, radius, body = self._AgentStates(p, v, robot)
        n, rho = self._AgentLines(*states, radius)
        no, rho_o = self._StaticLines(p)
        T, H, A, S = p.shape[0], self.H, self.A, self.S
        dn = np.zeros((T, H, A, 2, 8))
        drho = np.zeros((T, H, A, 8))
        for which in range(4):
            for c in range(2):
                pm = []
                for sign in (1.0, -1.0):
                    args = list(states)
                    args[which] = args[which].copy()
                    args[which][..., c] += sign * h
                    pm.append(self._AgentLines(*args, radius))
                dn[..., 2 * which + c] = (pm[0][0] - pm[1][0]) / (2 * h)
                drho[..., 2 * which + c] = (pm[0][1] - pm[1][1]) / (2 * h)
        dno = np.zeros((T, H, S, 2, 2))
        drho_o = np.zeros((T, H, S, 2))
        if S:
            for c in range(2):
                pm = []
                for sign in (1.0, -1.0):
                    q = p.copy()
                    q[..., c] += sign * h
                    pm.append(self._StaticLines(q))
                dno[..., c] = (pm[0][0] - pm[1][0]) / (2 * h)
                drho_o[..., c] = (pm[0][1] - pm[1][1]) / (2 * h)
        return (n, rho, no, rho_o), (dn, drho, dno, drho_o), body

    def Residuals(self, z, layout):
        """KKT residuals at z (for diagnostics and tests): stationarity (N,
        H, 2), primal c (N, H, R) and complementarity λ·c (N, H, R), with the
        slacks eliminated (ζ = λ/2M, module doc)."""
        p, v, robot = self.LocalState(z, layout)
        n, rho, no, rho_o = self.HalfPlanes(p, v, robot)
        return KktTerms(self, z, v, n, rho, no, rho_o)

    def WarmStart(self, z, previous=None, shift=1):
        """Human variables of the guess z: a forward simulation of each
        human's relaxed-ORCA QP along the robot's guess (positions, actions
        and multipliers: an exact KKT point to linearize at)."""
        z[self.p[0]] = self.p0
        self.ForwardSimulate(z, self.layout)

    def Restore(self, z):
        """The humans' exact relaxed-ORCA responses to z's robot plan, so the
        next SQP pass linearizes the KKT system at a point that satisfies it
        (a pass linearized at the previous QP's inexact KKT point was primal
        infeasible in a quarter of the steps with five people)."""
        self.ForwardSimulate(z, self.layout)

    def SolveHumanQps(self, humans, v, n, rho, no, rho_o):
        """The relaxed-ORCA QPs (humans/relaxed_orca.py) of the given humans
        (B,), batched: their current velocities v (B, 2) and half-planes
        (agents n (B, A, 2), ρ (B, A); static no (B, S, 2), ρ_o (B, S))."""

        cfg = self.config
        return relaxed_orca_actions(
            self.v_pref[humans],
            v,
            n,
            rho,
            max_speed=cfg.max_speed,
            max_accel=cfg.max_acceleration,
            time_step=self.dt,
            slack_weights=(cfg.slack_weight_acceleration, cfg.slack_weight_velocity),
            static_normals=no,
            static_offsets=rho_o,
        )

    def ForwardSimulate(self, z, layout):
        """Rolls the humans forward with the standalone relaxed-ORCA QP
        (humans/relaxed_orca.py), the robot fixed at z's plan; fills a, p, λ."""
        robot = self._RobotView(z, layout)
        v = self.v0.copy()
        active = np.nonzero(self.active)[0]
        for k in range(self.N):
            p = z[self.p[k]]
            n, rho, no, rho_o = self.HalfPlanes(p[None], v[None], robot.Step(k))
            a = np.zeros((self.H, 2))
            lam = np.zeros((self.H, self.R))
            sol = self.SolveHumanQps(
                active,
                v[active],
                n[0, active],
                rho[0, active],
                no[0, active],
                rho_o[0, active],
            )
            a[active] = sol.velocity
            lam[active] = np.concatenate(
                [
                    sol.multiplier_speed[:, None],
                    sol.multiplier_acceleration[:, None],
                    sol.multipliers_agents,
                    sol.multipliers_static,
                ],
                axis=1,
            )
            z[self.a[k]] = a
            z[self.lam[k]] = lam
            z[self.p[k + 1]] = p + self.dt * a
            v = a


def PredictionConsistency(predictor, z, layout) -> np.ndarray:
    """The honest check of the KKT embedding: re-solve every active human's
    relaxed-ORCA QP at the predicted states of plan z and return
    ‖a_QP − a_predicted‖ for every (k, j) (m/s), shape (N, active)."""

    p, v, robot = predictor.LocalState(z, layout)
    n, rho, no, rho_o = predictor.HalfPlanes(p, v, robot)
    a = z[predictor.a]
    active = np.nonzero(predictor.active)[0]
    N, B = predictor.N, len(active)
    humans = np.tile(active, N)
    sol = predictor.SolveHumanQps(
        humans,
        v[:, active].reshape(N * B, 2),
        n[:, active].reshape(N * B, predictor.A, 2),
        rho[:, active].reshape(N * B, predictor.A),
        no[:, active].reshape(N * B, predictor.S, 2),
        rho_o[:, active].reshape(N * B, predictor.S),
    )
    return np.linalg.norm(sol.velocity.reshape(N, B, 2) - a[:, active], axis=-1)
