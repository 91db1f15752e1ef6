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

from dataclasses import dataclass

import numpy as np

from sm2ith_drake.control.cbf import point_segment_distance_2d
from sm2ith_drake.control.program import ConstraintGroup, _BlockPattern
from sm2ith_drake.humans.orca import orca_agent_lines
from sm2ith_drake.humans.predictors import Predictor

_EPS = 1e-9


def orca_agent_half_planes(
    position,
    velocity,
    other_positions,
    other_velocities,
    combined_radius,
    share,
    *,
    tau,
    time_step,
):
    """Half-planes n·a ≥ ρ of ORCA, vectorized over leading axes.

    Returns n (..., 2) (unit, pointing into the allowed side) and ρ (...,).
    """
    u, d = orca_agent_lines(
        other_positions - position,
        velocity - other_velocities,
        combined_radius,
        tau=tau,
        time_step=time_step,
    )
    n = np.stack([-d[..., 1], d[..., 0]], axis=-1)
    point = velocity + np.asarray(share)[..., None] * u
    return n, np.sum(n * point, axis=-1)


def obstacle_half_planes(position, segments, radius, *, tau_obs):
    """Half-planes n·a ≥ ρ keeping an agent clear of static wall segments for
    τ_obs (van den Berg et al. 2011, Sec. 5.2, one line per segment): the
    velocities that do not reach the segment inflated by the radius within
    τ_obs. Vectorized: position (..., 2), segments (S, 2, 2) → n (..., S, 2),
    ρ (..., S).

    This is the conservative single-line form (the line through the closest
    point of the inflated segment, scaled by 1/τ_obs), not RVO2's full
    polygon-obstacle construction with its leg and "already covered" cases.
    """
    position = np.asarray(position, dtype=float)[..., None, :]
    A, B = segments[:, 0], segments[:, 1]
    AB = B - A
    s = np.clip(
        np.sum((position - A) * AB, axis=-1)
        / np.maximum(np.sum(AB * AB, axis=-1), _EPS),
        0.0,
        1.0,
    )
    closest = A + s[..., None] * AB
    diff = position - closest
    dist = np.linalg.norm(diff, axis=-1)
    n = diff / np.maximum(dist, _EPS)[..., None]
    # a·(−n) ≤ (dist − r)/τ_obs  ⟺  n·a ≥ −(dist − r)/τ_obs.
    return n, -(dist - radius) / tau_obs


@dataclass
class RobotView:
    """The robot at T steps as the people's ORCA sees it."""

    q: np.ndarray  # (T, n)
    nu: np.ndarray  # (T, m)
    p: np.ndarray  # (T, 2) base position
    v: np.ndarray  # (T, 2) base velocity in the world
    ends: np.ndarray  # (T, C, 2, 2) capsule axis end points on the floor
    ends_jacobian: np.ndarray  # (T, C, 2, 2, n) their Jacobians w.r.t. q
    radii: np.ndarray  # (C,)

    def Step(self, k: int) -> "RobotView":
        """The view of step k alone (T = 1)."""
        sl = slice(k, k + 1)
        return RobotView(
            self.q[sl],
            self.nu[sl],
            self.p[sl],
            self.v[sl],
            self.ends[sl],
            self.ends_jacobian[sl],
            self.radii,
        )


@dataclass
class NearestBody:
    """Per (step, person): the closest point on the axis of the robot capsule
    nearest to the person (surface distance), its radius, and the point's
    derivatives w.r.t. the configuration and the person's position."""

    point: np.ndarray  # (T, H, 2)
    radius: np.ndarray  # (T, H)
    d_dq: np.ndarray  # (T, H, 2, n)
    d_dp: np.ndarray  # (T, H, 2, 2)


def NearestBodies(robot: RobotView, positions) -> NearestBody:
    """The nearest robot body of every person (as humans/crowd.py's
    _NearestBody) with the derivatives of its closest point: for
    c = A + s(B − A), s = clip((P − A)·d / d·d) with d = B − A, the clipped
    ends move with A or B, and inside ∂s follows from the quotient rule."""
    P = np.asarray(positions, dtype=float)  # (T, H, 2)
    A = robot.ends[:, None, :, 0]  # (T, 1, C, 2)
    B = robot.ends[:, None, :, 1]
    d = B - A
    dd = np.sum(d * d, axis=-1)  # (T, 1, C)
    w = P[:, :, None] - A  # (T, H, C, 2)
    short = dd < 1e-9  # a vertical capsule is a point on the floor
    dist, s, _ = point_segment_distance_2d(A, B, P[:, :, None])  # (T, H, C)
    closest = A + s[..., None] * d  # (T, H, C, 2)
    i = np.argmin(dist - robot.radii, axis=-1)  # (T, H)
    T, H = P.shape[:2]
    t_idx, h_idx = np.meshgrid(np.arange(T), np.arange(H), indexing="ij")
    s_i = s[t_idx, h_idx, i]
    d_i = d[t_idx, 0, i]  # (T, H, 2)
    w_i = w[t_idx, h_idx, i]
    dd_i = dd[t_idx, 0, i]
    JA = robot.ends_jacobian[t_idx, i, 0]  # (T, H, 2, n)
    JB = robot.ends_jacobian[t_idx, i, 1]
    Jd = JB - JA
    d_dq = (1 - s_i)[..., None, None] * JA + s_i[..., None, None] * JB
    d_dp = np.zeros((T, H, 2, 2))
    inside = (s_i > 0) & (s_i < 1) & ~short[t_idx, 0, i]
    if np.any(inside):
        inv = 1.0 / np.where(inside, dd_i, 1.0)
        # ∂s/∂q = [d·(−J_A) + w·J_d − 2s d·J_d] / d·d;  ∂s/∂P = dᵀ / d·d.
        ds_dq = (
            -np.einsum("thi,thin->thn", d_i, JA)
            + np.einsum("thi,thin->thn", w_i, Jd)
            - 2 * s_i[..., None] * np.einsum("thi,thin->thn", d_i, Jd)
        ) * inv[..., None]
        ds_dq[~inside] = 0.0
        d_dq += d_i[..., :, None] * ds_dq[..., None, :]
        outer = d_i[..., :, None] * d_i[..., None, :] * inv[..., None, None]
        d_dp = np.where(inside[..., None, None], outer, 0.0)
    return NearestBody(
        point=closest[t_idx, h_idx, i],
        radius=robot.radii[i],
        d_dq=d_dq,
        d_dp=d_dp,
    )


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
        self._blocks = _KktBlocks(self, program.layout)
        self._equality = _KktEqualities(self, self._blocks)
        self._inequality = _KktInequalities(self, self._blocks)
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
        applied by the chain rule in _KktBlocks). Static lines depend on the
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
        return _KktTerms(self, z, v, n, rho, no, rho_o)

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
        from sm2ith_drake.humans.relaxed_orca import relaxed_orca_actions

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


def _KktTerms(pred, z, v, n, rho, no, rho_o):
    """Stationarity in a, primal constraints c and λ·c at z (module doc)."""
    cfg = pred.config
    a = z[pred.a]  # (N, H, 2)
    lam = z[pred.lam]  # (N, H, R)
    A = pred.A
    lam_s, lam_a = lam[..., 0], lam[..., 1]
    lam_i, lam_o = lam[..., 2 : 2 + A], lam[..., 2 + A :]
    stat = (
        2 * (a - pred.v_pref[None])
        + 2 * lam_s[..., None] * a
        + 2 * lam_a[..., None] * (a - v)
        - np.einsum("khi,khid->khd", lam_i, n)
        - np.einsum("kho,khod->khd", lam_o, no)
    )
    c_s = np.sum(a * a, axis=-1) - cfg.max_speed**2
    c_a = (
        np.sum((a - v) ** 2, axis=-1)
        - (pred.dt * cfg.max_acceleration) ** 2
        - lam_a / (2 * cfg.slack_weight_acceleration)
    )
    c_i = (
        rho - np.einsum("khid,khd->khi", n, a) - lam_i / (2 * cfg.slack_weight_velocity)
    )
    c_o = rho_o - np.einsum("khod,khd->kho", no, a)
    c = np.concatenate([c_s[..., None], c_a[..., None], c_i, c_o], axis=-1)
    return stat, c, lam * c


class _KktBlocks:
    """The local columns of every (k, j) block, shared by both KKT groups,
    and the derivatives at a point (computed once per point).

    Local columns of block (k, j): a (2), λ (R), then the state: own p (2),
    own v (2), each human neighbour's p and v (4 each), the robot's
    configuration q_k (n: the base through the base line, every joint
    through the nearest-body line) and base velocities ν_base (nb). A column
    whose value is a constant of the step (v_0 of every human) maps to −1
    and is dropped."""

    def __init__(self, pred, layout):
        self.pred = pred
        self.layout = layout
        self.R = pred.R
        self.n = pred.robot.num_positions
        self.nb = 3 if pred.robot.base_kind == "holonomic" else 2
        self.ilam = 2
        self.io = 2 + self.R  # own p, then own v
        self.inb = self.io + 4  # neighbour i: inb + 4i … inb + 4i + 3
        self.iq = self.inb + 4 * pred.K
        self.inu = self.iq + self.n
        self.width = self.inu + self.nb
        self.groups = []
        self._cache = {"key": None}
        self.columns = self._Columns()

    def _Columns(self):
        """(N, H, width) global column of every local column (−1: constant)."""
        pred, layout = self.pred, self.layout
        N, H, K = pred.N, pred.H, pred.K
        C = np.full((N, H, self.width), -1, dtype=int)
        C[:, :, 0:2] = pred.a
        C[:, :, self.ilam : self.ilam + self.R] = pred.lam
        C[:, :, self.io : self.io + 2] = pred.p[:-1]
        C[1:, :, self.io + 2 : self.io + 4] = pred.a[:-1]
        for i in range(K if pred.config.neighbor_derivatives else 0):
            other = pred.neighbors[:, i]
            c0 = self.inb + 4 * i
            C[:, :, c0 : c0 + 2] = pred.p[:-1][:, other]
            C[1:, :, c0 + 2 : c0 + 4] = pred.a[:-1][:, other]
        C[:, :, self.iq : self.inu] = np.asarray(layout.q)[:-1, None, :]
        C[:, :, self.inu :] = np.asarray(layout.nu)[:-1, None, : self.nb]
        return C

    def UpdatePattern(self):
        """After the neighbour sets changed: new columns, new patterns."""
        self.columns = self._Columns()
        self._cache = {"key": None}
        for group in self.groups:
            group.UpdatePattern()

    def Pattern(self, mask, rows_per_block, row_offset=0):
        """The structural nonzeros of ``mask`` (rows, width) in every block:
        (rows, cols, gather) with ``gather`` the flat index of each value in
        a dense (N, H, rows, width) array of local Jacobians."""
        N, H = self.pred.N, self.pred.H
        rr, cc = np.nonzero(mask)
        cols = self.columns[:, :, cc]  # (N, H, nnz)
        block = np.arange(N * H).reshape(N, H)[..., None]
        rows = row_offset + block * rows_per_block + rr
        gather = (block * rows_per_block + rr) * self.width + cc
        keep = cols >= 0
        return rows[keep], cols[keep], gather[keep]

    def StateDerivatives(self, J, rows, dX_own, dX_other, e):
        """Adds the derivatives of local rows w.r.t. the state to J.

        dX_own (N, H, r, 4): w.r.t. the own (p, v); dX_other (N, H, r, A, 4):
        through line i w.r.t. its other agent's (p, v). The robot's lines are
        the last two: the base's position is (x, y) of q and the nearest
        body's point moves with q and with the person's position
        (NearestBodies); both move with the base's world velocity G(q)ν,
        which depends on θ and ν_base."""
        pred, K = self.pred, self.pred.K
        J[:, :, rows, self.io : self.io + 4] += dX_own
        J[:, :, rows, self.inb : self.iq] += dX_other[..., :K, :].reshape(
            dX_other.shape[:3] + (4 * K,)
        )
        base, body = dX_other[..., K, :], dX_other[..., K + 1, :]  # (N,H,r,4)
        nearest = e["body"]
        J[:, :, rows, self.iq : self.iq + 2] += base[..., 0:2]
        J[:, :, rows, self.iq : self.inu] += np.einsum(
            "khri,khin->khrn", body[..., 0:2], nearest.d_dq
        )
        J[:, :, rows, self.io : self.io + 2] += np.einsum(
            "khri,khij->khrj", body[..., 0:2], nearest.d_dp
        )
        drv = base[..., 2:4] + body[..., 2:4]  # w.r.t. the base's velocity
        q, nu = e["robot"].q, e["robot"].nu
        for k in range(pred.N):
            G = pred.robot.G(q[k])[:2, : self.nb]
            dth = pred.robot.dGnu_dq(q[k], nu[k])[:2, 2]
            J[k, :, rows, self.iq + 2] += drv[k] @ dth
            J[k, :, rows, self.inu :] += drv[k] @ G

    def Evaluate(self, point):
        """Everything both groups need at a point, cached by the point."""
        if self._cache["key"] is point:
            return self._cache
        pred, layout = self.pred, self.layout
        z = point.z
        p = z[pred.p[:-1]]
        v = pred._HumanVelocities(z)
        robot = pred._RobotView(z, layout, point.kin)
        (n, rho, no, rho_o), (dn, drho, dno, drho_o), body = pred.HalfPlaneDerivatives(
            p, v, robot
        )
        stat, c, lc = _KktTerms(pred, z, v, n, rho, no, rho_o)
        self._cache = dict(
            key=point,
            v=v,
            n=n,
            rho=rho,
            no=no,
            rho_o=rho_o,
            dn=dn,
            drho=drho,
            dno=dno,
            drho_o=drho_o,
            stat=stat,
            c=c,
            lc=lc,
            robot=robot,
            body=body,
        )
        return self._cache


class _KktEqualities(ConstraintGroup):
    """Stationarity in a of every human's QP and the human dynamics (= 0)."""

    name = "orca_kkt_equalities"

    def __init__(self, pred, blocks):
        self.pred = pred
        self.blocks = blocks
        N, H = pred.N, pred.H
        self.num_kkt = N * H * 2
        self.num_rows = self.num_kkt + N * H * 2
        b = blocks
        # Stationarity depends on a, every λ and the whole local state.
        self.mask = np.ones((2, b.width), dtype=bool)
        row_blocks, col_blocks = [], []
        for k in range(N):
            for j in range(H):
                row_blocks.append(self.num_kkt + (k * H + j) * 2 + np.arange(2))
                col_blocks.append(
                    np.concatenate([pred.p[k + 1, j], pred.p[k, j], pred.a[k, j]])
                )
        self._dyn_rows, self._dyn_cols = _BlockPattern(row_blocks, col_blocks)
        blocks.groups.append(self)
        self.UpdatePattern()

    def UpdatePattern(self):
        rows, cols, self._gather = self.blocks.Pattern(self.mask, 2)
        self.rows = np.concatenate([rows, self._dyn_rows])
        self.cols = np.concatenate([cols, self._dyn_cols])

    def Eval(self, point):
        pred, b = self.pred, self.blocks
        e = b.Evaluate(point)
        z = point.z
        N, H, A, R = pred.N, pred.H, pred.A, b.R
        a, lam = z[pred.a], z[pred.lam]
        v = e["v"]
        J = np.zeros((N, H, 2, b.width))
        eye = np.eye(2)
        J[:, :, :, 0:2] = (2 + 2 * lam[..., 0] + 2 * lam[..., 1])[..., None, None] * eye
        il = b.ilam
        J[:, :, :, il] = 2 * a
        J[:, :, :, il + 1] = 2 * (a - v)
        J[:, :, :, il + 2 : il + 2 + A] = -np.swapaxes(e["n"], -1, -2)
        J[:, :, :, il + 2 + A : il + R] = -np.swapaxes(e["no"], -1, -2)
        # −Σ λ_i ∂n_i/∂x − Σ λ_o ∂n_o/∂x, and −2λ_a ∂v/∂v_own.
        lam_i = lam[..., 2 : 2 + A]
        dn = e["dn"]  # (N, H, A, 2, 8)
        dX_own = -np.einsum("khi,khidx->khdx", lam_i, dn[..., :4])
        dX_own[..., 0:2] -= np.einsum("kho,khodx->khdx", lam[..., 2 + A :], e["dno"])
        dX_own[..., 2:4] -= 2 * lam[..., 1, None, None] * eye
        dX_other = -np.einsum("khi,khidx->khdix", lam_i, dn[..., 4:])
        b.StateDerivatives(J, slice(0, 2), dX_own, dX_other, e)
        # Dynamics p_{k+1} − p_k − Δt a_k.
        p = z[pred.p]
        g_dyn = p[1:] - p[:-1] - pred.dt * a
        block = np.concatenate([eye, -eye, -pred.dt * eye], axis=1)  # (2, 6)
        vals_dyn = np.broadcast_to(block, (N, H, 2, 6)).reshape(-1)
        g = np.concatenate([e["stat"].reshape(-1), g_dyn.reshape(-1)])
        return g, np.concatenate([J.reshape(-1)[self._gather], vals_dyn])


class _KktInequalities(ConstraintGroup):
    """Primal feasibility c ≤ 0 and relaxed complementarity λ·c ≥ −ε of
    every human's QP (dual feasibility λ ≥ 0 is a bound)."""

    name = "orca_kkt_inequalities"

    def __init__(self, pred, blocks):
        self.pred = pred
        self.blocks = blocks
        N, H, A, K = pred.N, pred.H, pred.A, pred.K
        b, R = blocks, blocks.R
        self.ri = 2 * R
        self.num_rows = N * H * self.ri
        primal = np.zeros((R, b.width), dtype=bool)
        primal[:, 0:2] = True  # every c depends on a
        own_p = np.arange(b.io, b.io + 2)
        own_v = own_p + 2
        primal[1, [b.ilam + 1, *own_v]] = True  # c_a: λ_a, v_own
        for i in range(A):  # agent lines: λ_i, own and agent i's state
            r = 2 + i
            primal[r, b.ilam + r] = True
            primal[r, b.io : b.io + 4] = True
            if i < K:
                primal[r, b.inb + 4 * i : b.inb + 4 * i + 4] = True
            elif i == K:  # the robot base: (x, y, θ), ν_base
                primal[r, b.iq : b.iq + 3] = True
                primal[r, b.inu :] = True
            else:  # the nearest body: all of q, ν_base
                primal[r, b.iq :] = True
        primal[2 + A :, own_p] = True  # static lines: own position only
        self.mask = np.concatenate([primal, primal], axis=0)
        self.mask[R + np.arange(R), b.ilam + np.arange(R)] = True
        blocks.groups.append(self)
        self.UpdatePattern()

    def UpdatePattern(self):
        self.rows, self.cols, self._gather = self.blocks.Pattern(self.mask, self.ri)

    def Bounds(self, eps):
        R = self.blocks.R
        lo = np.concatenate([np.full(R, -np.inf), np.full(R, -eps)])
        hi = np.concatenate([np.zeros(R), np.full(R, np.inf)])
        count = self.pred.N * self.pred.H
        return np.tile(lo, count), np.tile(hi, count)

    def Eval(self, point):
        pred, b = self.pred, self.blocks
        e = b.Evaluate(point)
        z = point.z
        cfg = pred.config
        N, H, A, R = pred.N, pred.H, pred.A, b.R
        a, lam = z[pred.a], z[pred.lam]
        v, c = e["v"], e["c"]
        il = b.ilam
        dc = np.zeros((N, H, R, b.width))
        dc[:, :, 0, 0:2] = 2 * a
        dc[:, :, 1, 0:2] = 2 * (a - v)
        dc[:, :, 1, il + 1] = -0.5 / cfg.slack_weight_acceleration
        dc[:, :, 1, b.io + 2 : b.io + 4] = -2 * (a - v)
        dc[:, :, 2 : 2 + A, 0:2] = -e["n"]
        dc[:, :, 2 + A :, 0:2] = -e["no"]
        dc[:, :, np.arange(2, 2 + A), il + np.arange(2, 2 + A)] = (
            -0.5 / cfg.slack_weight_velocity
        )
        # Agent line i: ∂(ρ_i − n_iᵀa)/∂x through its own and other state.
        dX = e["drho"] - np.einsum("khidx,khd->khix", e["dn"], a)  # (N,H,A,8)
        dX_own = np.zeros((N, H, R, 4))
        dX_own[:, :, 2 : 2 + A] = dX[..., :4]
        dX_own[:, :, 2 + A :, 0:2] = e["drho_o"] - np.einsum(
            "khodx,khd->khox", e["dno"], a
        )
        dX_other = np.zeros((N, H, R, A, 4))
        dX_other[:, :, np.arange(2, 2 + A), np.arange(A)] = dX[..., 4:]
        b.StateDerivatives(dc, slice(0, R), dX_own, dX_other, e)
        # Complementarity λ_r c_r.
        dlc = lam[..., None] * dc
        dlc[:, :, np.arange(R), il + np.arange(R)] += c
        g = np.concatenate([c, e["lc"]], axis=-1)
        J = np.concatenate([dc, dlc], axis=2)
        return g.reshape(-1), J.reshape(-1)[self._gather]


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
