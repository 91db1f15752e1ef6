"""SM²ITH's interactive human prediction: the relaxed-ORCA QP of every human
at every step, embedded in the MPC through its KKT conditions (eq. smith).

For human j at step k (state: positions p_k, velocities v_k of everyone and
the robot base), the action a = a_{k,j} and slacks ζ = (ζ_a, ζ_v) solve

    min  ‖a − v_pref‖² + M_a ζ_a² + M_v ‖ζ_v‖²
    s.t. c_s  = ‖a‖² − a_max² ≤ 0                        (speed)
         c_a  = ‖a − v_k‖² − (Δt·acc_max)² − ζ_a ≤ 0       (acceleration)
         c_i  = ρ_i − n_iᵀa − ζ_v,i ≤ 0                    (agent i's ORCA line)
         c_o  = ρ_o − n_oᵀa ≤ 0                            (static obstacle lines)
         −ζ ≤ 0,

with (n, ρ) the ORCA half-planes as RVO2 builds them from the state. (The
paper writes the acceleration slack as tightening the constraint; a slack
that keeps the QP feasible must relax it, as here.) The MPC carries a, ζ,
the multipliers λ of c and μ of −ζ ≤ 0 as decision variables, with

    stationarity   2(a − v_pref) + 2λ_s a + 2λ_a (a − v_k) − Σ λ_i n_i − Σ λ_o n_o = 0,
                   2M_a ζ_a − λ_a − μ_a = 0,   2M_v ζ_v,i − λ_i − μ_i = 0,
    primal         c ≤ 0,   dual  λ, μ ≥ 0,
    complementarity (relaxed)  λ·c ≥ −ε,  μ·ζ ≤ ε,

and the human dynamics p_{k+1} = p_k + Δt a_k, v_{k+1} = a_k. Exact
complementarity (ε = 0) violates the usual constraint qualifications; the
relaxation ε is ``complementarity_relaxation`` (chosen by measurement, see
the README).

The half-planes depend on the predicted states, so the robot's plan moves
the predicted humans: that is the interaction. Their Jacobians w.r.t. the
states are taken by central differences of the vectorized ORCA agent lines
of humans/orca.py, the same geometry the reference uses (piecewise smooth).
"""

import numpy as np

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
        self.A = H  # agent lines per human: H − 1 humans + the robot
        self.S = len(self.segments)
        self.v_pref = np.zeros((H, 2))
        # Fixed per agent line (human j's lines: humans i ≠ j, then the robot):
        # the other humans' indices, the combined radii and the shares.
        self._others = np.array(
            [[i for i in range(H) if i != j] for j in range(H)], dtype=int
        ).reshape(H, H - 1)
        self._radius = np.full(self.A, 2 * self.human_radius)
        self._radius[-1] = self.human_radius + self.robot_radius
        self._share = np.full(self.A, 0.5)
        self._share[-1] = config.robot_share

    # -------------------------------------------------------------- variables

    def AddVariables(self, layout):
        super().AddVariables(layout)
        N, H, A, S = self.N, self.H, self.A, self.S
        self.a = layout.AddVariables("human_a", (N, H, 2))
        self.zeta_a = layout.AddVariables("human_zeta_a", (N, H))
        self.zeta_v = layout.AddVariables("human_zeta_v", (N, H, A))
        self.lam = layout.AddVariables("human_lambda", (N, H, 2 + A + S))
        self.mu = layout.AddVariables("human_mu", (N, H, 1 + A))

    def ConstraintGroups(self, program):
        blocks = _KktBlocks(self, program.layout)
        self._equality = _KktEqualities(self, blocks)
        self._inequality = _KktInequalities(self, blocks)
        eps = self.config.complementarity_relaxation
        lo, hi = self._inequality.Bounds(eps)
        m = self._equality.num_rows
        return [(self._equality, np.zeros(m), np.zeros(m)), (self._inequality, lo, hi)]

    def ApplyBounds(self, lower, upper):
        lower[self.p[0]] = upper[self.p[0]] = self.p0
        for idx in (self.zeta_a, self.zeta_v, self.lam, self.mu):
            lower[idx] = 0.0

    def SetHumans(self, estimate):
        super().SetHumans(estimate)
        self.v_pref = self.v0.copy()

    # ---------------------------------------------------------------- model

    def _HumanVelocities(self, z):
        """v_k of every human for k = 0 … N−1: (N, H, 2)."""
        a = z[self.a]
        return np.concatenate([self.v0[None], a[:-1]], axis=0)

    def _RobotStates(self, z, layout):
        """Robot base position and world velocity at k = 0 … N−1."""
        q = z[layout.q[:-1]]
        nu = z[layout.nu[:-1]]
        vel = np.stack([self.robot.G(q[k]) @ nu[k] for k in range(self.N)])[:, :2]
        return q[:, :2], vel

    def HalfPlanes(self, positions, velocities, robot_p, robot_v):
        """Agent lines (n (K, H, A, 2), ρ (K, H, A)) and static lines
        (n (K, H, S, 2), ρ (K, H, S)) for states of shape (K, H, 2)."""
        K, H = positions.shape[0], self.H
        others = self._others
        op = np.concatenate(
            [
                positions[:, others],
                np.broadcast_to(robot_p[:, None, None], (K, H, 1, 2)),
            ],
            axis=2,
        )
        ov = np.concatenate(
            [
                velocities[:, others],
                np.broadcast_to(robot_v[:, None, None], (K, H, 1, 2)),
            ],
            axis=2,
        )
        radius, share = self._radius, self._share
        n, rho = orca_agent_half_planes(
            positions[:, :, None],
            velocities[:, :, None],
            op,
            ov,
            radius,
            share,
            tau=self.config.tau,
            time_step=self.dt,
        )
        if self.S:
            no, rho_o = obstacle_half_planes(
                positions, self.segments, self.human_radius, tau_obs=self.config.tau_obs
            )
        else:
            no, rho_o = np.zeros((K, H, 0, 2)), np.zeros((K, H, 0))
        return n, rho, no, rho_o

    def LocalState(self, z, layout):
        """The states the k-th QPs depend on, k = 0 … N−1: human positions
        and velocities (N, H, 2), robot base position and velocity (N, 2)."""
        p = z[self.p[:-1]]
        v = self._HumanVelocities(z)
        rp, rv = self._RobotStates(z, layout)
        return p, v, rp, rv

    def HalfPlaneDerivatives(self, p, v, rp, rv, h=1e-6):
        """Half-planes and their central-difference derivatives w.r.t. the
        local state s = (p (2H), v (2H), rp (2), rv (2)), for all k at once:
        dn (K, H, A, 2, D), drho (K, H, A, D), dno (K, H, S, 2, D),
        drho_o (K, H, S, D).

        Each agent line depends only on its own human's state and on one
        other agent's, so every line is differenced at once: 8 perturbations
        of (own p, own v, other p, other v) and 2 of the static lines' own p,
        whatever the number of people (differencing every entry of s instead
        costs 2(4H + 4) evaluations of every line: O(H³) work)."""
        K, H, A = p.shape[0], self.H, self.A
        D = 4 * H + 4
        base = self.HalfPlanes(p, v, rp, rv)
        shape = (K, H, A, 2)
        sp = np.broadcast_to(p[:, :, None], shape)
        sv = np.broadcast_to(v[:, :, None], shape)
        op = np.concatenate(
            [p[:, self._others], np.broadcast_to(rp[:, None, None], (K, H, 1, 2))],
            axis=2,
        )
        ov = np.concatenate(
            [v[:, self._others], np.broadcast_to(rv[:, None, None], (K, H, 1, 2))],
            axis=2,
        )
        # Column of component 0 of each line's own / other p and v in s.
        own = np.broadcast_to(2 * np.arange(H)[:, None], (H, A))
        other = np.concatenate([2 * self._others, np.full((H, 1), 4 * H)], axis=1)
        other_v = np.concatenate(
            [2 * H + 2 * self._others, np.full((H, 1), 4 * H + 2)], axis=1
        )
        columns = (own, own + 2 * H, other, other_v)
        J = np.broadcast_to(np.arange(H)[:, None], (H, A))
        L = np.broadcast_to(np.arange(A)[None, :], (H, A))
        dn = np.zeros((K, H, A, D, 2))
        drho = np.zeros((K, H, A, D))
        inputs = [sp, sv, op, ov]
        for which, col0 in enumerate(columns):
            for c in range(2):
                results = []
                for sign in (1.0, -1.0):
                    args = list(inputs)
                    args[which] = args[which].copy()
                    args[which][..., c] += sign * h
                    results.append(
                        orca_agent_half_planes(
                            *args,
                            self._radius,
                            self._share,
                            tau=self.config.tau,
                            time_step=self.dt,
                        )
                    )
                (n_plus, r_plus), (n_minus, r_minus) = results
                dn[:, J, L, col0 + c] = (n_plus - n_minus) / (2 * h)
                drho[:, J, L, col0 + c] = (r_plus - r_minus) / (2 * h)
        dn = np.moveaxis(dn, 3, 4)
        S = self.S
        dno = np.zeros((K, H, S, 2, D))
        drho_o = np.zeros((K, H, S, D))
        if S:
            JS = np.broadcast_to(np.arange(H)[:, None], (H, S))
            LS = np.broadcast_to(np.arange(S)[None, :], (H, S))
            dno_t = np.zeros((K, H, S, D, 2))
            for c in range(2):
                results = []
                for sign in (1.0, -1.0):
                    q = p.copy()
                    q[..., c] += sign * h
                    results.append(
                        obstacle_half_planes(
                            q,
                            self.segments,
                            self.human_radius,
                            tau_obs=self.config.tau_obs,
                        )
                    )
                (n_plus, r_plus), (n_minus, r_minus) = results
                col = 2 * JS + c
                dno_t[:, JS, LS, col] = (n_plus - n_minus) / (2 * h)
                drho_o[:, JS, LS, col] = (r_plus - r_minus) / (2 * h)
            dno = np.moveaxis(dno_t, 3, 4)
        return base, [dn, drho, dno, drho_o]

    def Residuals(self, z, layout):
        """KKT residuals at z (for diagnostics and tests): stationarity (N,
        H, 2), primal c (N, H, 2+A+S), complementarity λ·c (N, H, 2+A+S)."""
        p, v, rp, rv = self.LocalState(z, layout)
        n, rho, no, rho_o = self.HalfPlanes(p, v, rp, rv)
        return _KktTerms(self, z, v, n, rho, no, rho_o)

    def WarmStart(self, z, previous=None, shift=1):
        """Human variables of the guess z: a forward simulation of each
        human's relaxed-ORCA QP along the robot's guess (positions, actions,
        slacks and multipliers: an exact KKT point to linearize at)."""
        z[self.p[0]] = self.p0
        self.ForwardSimulate(z, self.layout)

    def SolveHumanQp(self, j, v, n, rho, no, rho_o):
        """Human j's relaxed-ORCA QP (humans/relaxed_orca.py) with its current
        velocity v and half-planes (agents n, ρ; static no, ρ_o)."""
        from sm2ith_drake.humans.relaxed_orca import relaxed_orca_action

        cfg = self.config
        return relaxed_orca_action(
            self.v_pref[j],
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
        (humans/orca.py), the robot fixed at z's plan; fills a, p, ζ, λ, μ."""

        rp_all, rv_all = self._RobotStates(z, layout)
        v = self.v0.copy()
        for k in range(self.N):
            p = z[self.p[k]]
            n, rho, no, rho_o = self.HalfPlanes(
                p[None], v[None], rp_all[k : k + 1], rv_all[k : k + 1]
            )
            a = np.zeros((self.H, 2))
            for j in range(self.H):
                if not self.active[j]:
                    for idx in (self.zeta_a, self.zeta_v, self.lam, self.mu):
                        z[idx[k, j]] = 0.0
                    continue
                sol = self.SolveHumanQp(
                    j, v[j], n[0, j], rho[0, j], no[0, j], rho_o[0, j]
                )
                a[j] = sol.velocity
                z[self.zeta_a[k, j]] = sol.slack_acceleration
                z[self.zeta_v[k, j]] = sol.slack_velocity
                z[self.lam[k, j]] = np.concatenate(
                    [
                        [sol.multiplier_speed, sol.multiplier_acceleration],
                        sol.multipliers_agents,
                        sol.multipliers_static,
                    ]
                )
                z[self.mu[k, j]] = np.concatenate(
                    [
                        [sol.multiplier_slack_acceleration],
                        sol.multipliers_slack_velocity,
                    ]
                )
            z[self.a[k]] = a
            z[self.p[k + 1]] = p + self.dt * a
            v = a


def _KktTerms(pred, z, v, n, rho, no, rho_o):
    """Stationarity in a, primal constraints c and λ·c at z (see module)."""
    cfg = pred.config
    a = z[pred.a]  # (N, H, 2)
    lam = z[pred.lam]  # (N, H, 2+A+S)
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
        - z[pred.zeta_a]
    )
    c_i = rho - np.einsum("khid,khd->khi", n, a) - z[pred.zeta_v]
    c_o = rho_o - np.einsum("khod,khd->kho", no, a)
    c = np.concatenate([c_s[..., None], c_a[..., None], c_i, c_o], axis=-1)
    return stat, c, lam * c


class _KktBlocks:
    """Shared bookkeeping of the two KKT groups: the local columns of each
    (k, j) block and the derivatives at a point (computed once per point)."""

    def __init__(self, pred, layout):
        self.pred = pred
        self.layout = layout
        N, H, A, S = pred.N, pred.H, pred.A, pred.S
        self.R = 2 + A + S
        self.nb = 3 if pred.robot.base_kind == "holonomic" else 2

        def own(k, j):
            return np.concatenate(
                [
                    pred.a[k, j],
                    [pred.zeta_a[k, j]],
                    pred.zeta_v[k, j],
                    pred.lam[k, j],
                    pred.mu[k, j],
                ]
            )

        self.num_own = 2 + 1 + A + self.R + 1 + A
        self.cols = {}
        for k in range(N):
            state = [pred.p[k].ravel()]
            if k > 0:
                state.append(pred.a[k - 1].ravel())
            state += [layout.q[k][:3], layout.nu[k][: self.nb]]
            for j in range(H):
                self.cols[k, j] = np.concatenate([own(k, j)] + state)
        o = self.num_own
        self.ip = slice(o, o + 2 * H)
        self.iv = slice(o + 2 * H, o + 4 * H)
        self.iq = slice(o + 4 * H, o + 4 * H + 3)
        self.inu = slice(o + 4 * H + 3, o + 4 * H + 3 + self.nb)
        self.width = o + 4 * H + 3 + self.nb
        self.keep0 = np.r_[np.arange(o + 2 * H), np.arange(o + 4 * H, self.width)]
        self._cache = {"key": None}

    def AgentColumns(self, j, i):
        """Local state columns of human j's i-th other agent (the humans
        i ≠ j in order, then the robot base)."""
        H = self.pred.H
        if i < H - 1:
            other = [h for h in range(H) if h != j][i]
            return np.r_[
                self.ip.start + 2 * other + np.arange(2),
                self.iv.start + 2 * other + np.arange(2),
            ]
        return np.r_[
            np.arange(self.iq.start, self.iq.stop),
            np.arange(self.inu.start, self.inu.stop),
        ]

    def OwnStateColumns(self, j):
        return (
            self.ip.start + 2 * j + np.arange(2),
            self.iv.start + 2 * j + np.arange(2),
        )

    def _Mask(self, masks, k, j):
        return masks[j] if k > 0 else masks[j][:, self.keep0]

    def Pattern(self, row_offset_of, masks):
        """Rows and columns of the structural nonzeros ``masks`` (H, rows,
        width) of every (k, j) block (k = 0 has no velocity columns)."""
        rows, cols = [], []
        for (k, j), block_cols in self.cols.items():
            rr, cc = np.nonzero(self._Mask(masks, k, j))
            rows.append(row_offset_of(k, j) + rr)
            cols.append(block_cols[cc])
        return np.concatenate(rows), np.concatenate(cols)

    def Flatten(self, J, masks):
        """The values of dense local Jacobians J (N, H, rows, width) at the
        structural nonzeros, in the pattern's order."""
        out = []
        for k, j in self.cols:
            block = J[k, j] if k > 0 else J[k, j][:, self.keep0]
            out.append(block[self._Mask(masks, k, j)])
        return np.concatenate(out)

    def StateToColumns(self, dX, q, nu):
        """Maps derivatives w.r.t. the local state (…, D) (k-leading) to the
        state columns (…, 4H + 3 + nb) through the robot's base velocity."""
        pred, H = self.pred, self.pred.H
        N = dX.shape[0]
        out = np.zeros(dX.shape[:-1] + (4 * H + 3 + self.nb,))
        out[..., : 4 * H] = dX[..., : 4 * H]
        out[..., 4 * H : 4 * H + 2] = dX[..., 4 * H : 4 * H + 2]
        drv = dX[..., 4 * H + 2 : 4 * H + 4]  # w.r.t. the robot base velocity
        for k in range(N):
            G = pred.robot.G(q[k])[:2, : self.nb]
            dth = pred.robot.dGnu_dq(q[k], nu[k])[:2, 2]
            out[k, ..., 4 * H + 2] = drv[k] @ dth
            out[k, ..., 4 * H + 3 :] = drv[k] @ G
        return out

    def Evaluate(self, point):
        """Everything both groups need at a point, cached by the point."""
        if self._cache["key"] is point:
            return self._cache
        pred, layout = self.pred, self.layout
        z = point.z
        p, v, rp, rv = pred.LocalState(z, layout)
        (n, rho, no, rho_o), (dn, drho, dno, drho_o) = pred.HalfPlaneDerivatives(
            p, v, rp, rv
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
            q=z[layout.q[:-1]],
            nu=z[layout.nu[:-1]],
        )
        return self._cache


class _KktEqualities(ConstraintGroup):
    """Stationarity of every human's QP and the human dynamics (= 0)."""

    name = "orca_kkt_equalities"

    def __init__(self, pred, blocks):
        self.pred = pred
        self.blocks = blocks
        N, H, A = pred.N, pred.H, pred.A
        self.re = 2 + 1 + A
        self.num_kkt = N * H * self.re
        self.num_rows = self.num_kkt + N * H * 2
        b, R = self.blocks, self.blocks.R
        ilam, imu = 3 + A, 3 + A + R
        self.masks = np.zeros((H, self.re, b.width), dtype=bool)
        m = self.masks
        m[:, 0:2, 0:2] = True  # stationarity in a: a, every λ, every state
        m[:, 0:2, ilam : ilam + R] = True
        m[:, 0:2, b.ip.start :] = True
        m[:, 2, [2, ilam + 1, imu]] = True  # in ζ_a
        for i in range(A):  # in ζ_v,i
            m[:, 3 + i, [3 + i, ilam + 2 + i, imu + 1 + i]] = True
        kkt_rows, kkt_cols = b.Pattern(lambda k, j: (k * H + j) * self.re, m)
        row_blocks, col_blocks = [], []
        for k in range(N):
            for j in range(H):
                row_blocks.append(self.num_kkt + (k * H + j) * 2 + np.arange(2))
                col_blocks.append(
                    np.concatenate([pred.p[k + 1, j], pred.p[k, j], pred.a[k, j]])
                )
        dyn_rows, dyn_cols = _BlockPattern(row_blocks, col_blocks)
        self.rows = np.concatenate([kkt_rows, dyn_rows])
        self.cols = np.concatenate([kkt_cols, dyn_cols])

    def Eval(self, point):
        pred, b = self.pred, self.blocks
        e = b.Evaluate(point)
        z = point.z
        N, H, A, R = pred.N, pred.H, pred.A, b.R
        cfg = pred.config
        a, lam = z[pred.a], z[pred.lam]
        v = e["v"]
        J = np.zeros((N, H, self.re, b.width))
        eye = np.eye(2)
        # Stationarity in a.
        J[:, :, 0:2, 0:2] = (2 + 2 * lam[..., 0] + 2 * lam[..., 1])[
            ..., None, None
        ] * eye
        ilam = 3 + A
        J[:, :, 0:2, ilam] = 2 * a
        J[:, :, 0:2, ilam + 1] = 2 * (a - v)
        J[:, :, 0:2, ilam + 2 : ilam + 2 + A] = -np.swapaxes(e["n"], -1, -2)
        J[:, :, 0:2, ilam + 2 + A : ilam + R] = -np.swapaxes(e["no"], -1, -2)
        dX = -(
            np.einsum("khi,khidx->khdx", lam[..., 2 : 2 + A], e["dn"])
            + np.einsum("kho,khodx->khdx", lam[..., 2 + A :], e["dno"])
        )
        J[:, :, 0:2, b.ip.start :] = b.StateToColumns(dX, e["q"], e["nu"])
        for j in range(H):  # the explicit v_k of human j (k ≥ 1 columns)
            J[:, j, 0:2, b.iv.start + 2 * j : b.iv.start + 2 * j + 2] += (
                -2 * lam[:, j, 1][:, None, None] * eye
            )
        # Stationarity in ζ_a and ζ_v.
        imu = ilam + R
        J[:, :, 2, 2] = 2 * cfg.slack_weight_acceleration
        J[:, :, 2, ilam + 1] = -1.0
        J[:, :, 2, imu] = -1.0
        for i in range(A):
            J[:, :, 3 + i, 3 + i] = 2 * cfg.slack_weight_velocity
            J[:, :, 3 + i, ilam + 2 + i] = -1.0
            J[:, :, 3 + i, imu + 1 + i] = -1.0
        g_stat_za = (
            2 * cfg.slack_weight_acceleration * z[pred.zeta_a]
            - lam[..., 1]
            - z[pred.mu][..., 0]
        )
        g_stat_zv = (
            2 * cfg.slack_weight_velocity * z[pred.zeta_v]
            - lam[..., 2 : 2 + A]
            - z[pred.mu][..., 1:]
        )
        g_kkt = np.concatenate([e["stat"], g_stat_za[..., None], g_stat_zv], axis=-1)
        # Dynamics p_{k+1} − p_k − Δt a_k.
        p = z[pred.p]
        g_dyn = p[1:] - p[:-1] - pred.dt * a
        block = np.concatenate([eye, -eye, -pred.dt * eye], axis=1)  # (2, 6)
        vals_dyn = np.broadcast_to(block, (N, H, 2, 6)).reshape(-1)
        g = np.concatenate([g_kkt.reshape(-1), g_dyn.reshape(-1)])
        return g, np.concatenate([b.Flatten(J, self.masks), vals_dyn])


class _KktInequalities(ConstraintGroup):
    """Primal feasibility c ≤ 0 and relaxed complementarity λ·c ≥ −ε,
    μ·ζ ≤ ε of every human's QP (dual feasibility λ, μ ≥ 0 are bounds)."""

    name = "orca_kkt_inequalities"

    def __init__(self, pred, blocks):
        self.pred = pred
        self.blocks = blocks
        N, H, A = pred.N, pred.H, pred.A
        R = self.blocks.R
        self.ri = 2 * R + 1 + A
        self.num_rows = N * H * self.ri
        b = self.blocks
        ilam, imu = 3 + A, 3 + A + R
        self.masks = np.zeros((H, self.ri, b.width), dtype=bool)
        for j in range(H):
            m = self.masks[j]
            own_p, own_v = b.OwnStateColumns(j)
            primal = np.zeros((R, b.width), dtype=bool)
            primal[:, 0:2] = True  # every c depends on a
            primal[1, 2] = True  # c_a: ζ_a and v_j
            primal[1, own_v] = True
            for i in range(A):  # agent lines: ζ_v,i, own and agent i's state
                primal[2 + i, 3 + i] = True
                primal[2 + i, own_p] = True
                primal[2 + i, own_v] = True
                primal[2 + i, b.AgentColumns(j, i)] = True
            primal[2 + A :, own_p] = True  # static lines: own position only
            m[:R] = primal
            m[R : 2 * R] = primal
            m[R + np.arange(R), ilam + np.arange(R)] = True
            for r in range(1 + A):
                m[2 * R + r, [2 + r, imu + r]] = True
        self.rows, self.cols = b.Pattern(lambda k, j: (k * H + j) * self.ri, self.masks)

    def Bounds(self, eps):
        pred, R = self.pred, self.blocks.R
        lo = np.concatenate(
            [np.full(R, -np.inf), np.full(R, -eps), np.full(1 + pred.A, -np.inf)]
        )
        hi = np.concatenate([np.zeros(R), np.full(R, np.inf), np.full(1 + pred.A, eps)])
        count = pred.N * pred.H
        return np.tile(lo, count), np.tile(hi, count)

    def Eval(self, point):
        pred, b = self.pred, self.blocks
        e = b.Evaluate(point)
        z = point.z
        N, H, A, R = pred.N, pred.H, pred.A, b.R
        a, lam, mu = z[pred.a], z[pred.lam], z[pred.mu]
        v, c = e["v"], e["c"]
        # Primal rows: dc (N, H, R, width).
        dc = np.zeros((N, H, R, b.width))
        dc[:, :, 0, 0:2] = 2 * a
        dc[:, :, 1, 0:2] = 2 * (a - v)
        dc[:, :, 1, 2] = -1.0
        for j in range(H):
            dc[:, j, 1, b.iv.start + 2 * j : b.iv.start + 2 * j + 2] = (
                -2 * (a - v)[:, j]
            )
        dc[:, :, 2 : 2 + A, 0:2] = -e["n"]
        dc[:, :, 2 + A :, 0:2] = -e["no"]
        for i in range(A):
            dc[:, :, 2 + i, 3 + i] = -1.0
        dX_i = e["drho"] - np.einsum("khidx,khd->khix", e["dn"], a)
        dX_o = e["drho_o"] - np.einsum("khodx,khd->khox", e["dno"], a)
        dc[:, :, 2:, b.ip.start :] += b.StateToColumns(
            np.concatenate([dX_i, dX_o], axis=2), e["q"], e["nu"]
        )
        # Complementarity λ_r c_r.
        ilam = 3 + A
        dlc = lam[..., None] * dc
        for r in range(R):
            dlc[:, :, r, ilam + r] += c[..., r]
        # μ·ζ.
        zeta = np.concatenate([z[pred.zeta_a][..., None], z[pred.zeta_v]], axis=-1)
        dmz = np.zeros((N, H, 1 + A, b.width))
        imu = ilam + R
        for r in range(1 + A):
            dmz[:, :, r, 2 + r] = mu[..., r]
            dmz[:, :, r, imu + r] = zeta[..., r]
        g = np.concatenate([c, e["lc"], mu * zeta], axis=-1)
        J = np.concatenate([dc, dlc, dmz], axis=2)
        return g.reshape(-1), b.Flatten(J, self.masks)


def PredictionConsistency(predictor, z, layout) -> np.ndarray:
    """The honest check of the KKT embedding: re-solve every active human's
    relaxed-ORCA QP at the predicted states of plan z and return
    ‖a_QP − a_predicted‖ for every (k, j) (m/s), shape (N, active)."""

    p, v, rp, rv = predictor.LocalState(z, layout)
    n, rho, no, rho_o = predictor.HalfPlanes(p, v, rp, rv)
    a = z[predictor.a]
    active = np.nonzero(predictor.active)[0]
    errors = np.zeros((predictor.N, len(active)))
    for k in range(predictor.N):
        for col, j in enumerate(active):
            sol = predictor.SolveHumanQp(
                j, v[k, j], n[k, j], rho[k, j], no[k, j], rho_o[k, j]
            )
            errors[k, col] = np.linalg.norm(sol.velocity - a[k, j])
    return errors
