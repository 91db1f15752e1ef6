"""The ORCA-KKT constraint groups of SM²ITH (eq. smith), as
ConstraintGroups with fixed patterns (the derivation is in orca_kkt.py):

- KktEqualities: stationarity in a of every human's relaxed-ORCA QP
  (eq. smith_kkt_stationarity) and the human dynamics p_{k+1} = p_k + Δt a_k
  (eq. smith_humdyn);
- KktInequalities: primal feasibility c ≤ 0 (eq. smith_kkt_primal) and
  relaxed complementarity λ·c ≥ −ε (eq. smith_kkt_complementarity); dual
  feasibility λ ≥ 0 (eq. smith_kkt_dual) is a variable bound
  (OrcaKkt.ApplyBounds).
"""

from dataclasses import dataclass

import numpy as np

from sm2ith_drake.control.groups import ConstraintGroup
from sm2ith_drake.geometry import einsum
from sm2ith_drake.robots.planar_base import NumBaseVelocities, VelocityMapPatterns


def KktTerms(pred, z, v, n, rho, no, rho_o):
    """Stationarity in a, primal constraints c and λ·c at z (module doc),
    over the T steps the half-planes n (T, H, A, 2) are of."""
    cfg = pred.config
    T = n.shape[0]
    a = z[pred.a[:T]]  # (T, H, 2)
    lam = z[pred.lam[:T]]  # (T, H, R)
    A = pred.num_agent_lines
    lam_s, lam_a = lam[..., 0], lam[..., 1]
    lam_i, lam_o = lam[..., 2 : 2 + A], lam[..., 2 + A :]
    stat = (
        2 * (a - pred.v_pref[None])
        + 2 * lam_s[..., None] * a
        + 2 * lam_a[..., None] * (a - v)
        - np.einsum("khi,khid->khd", lam_i, n)
        - einsum("kho,khod->khd", lam_o, no)
    )
    c_s = np.sum(a * a, axis=-1) - pred.max_speed[None] ** 2
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


@dataclass
class KktPointData:
    """The KKT terms at one linearization point and their ingredients."""

    point: object  # the LinearizationPoint these are of
    v: np.ndarray  # human velocities v_k (N, H, 2)
    n: np.ndarray  # agent line normals (N, H, A, 2)
    rho: np.ndarray  # agent line offsets (N, H, A)
    no: np.ndarray  # static line normals (N, H, S, 2)
    rho_o: np.ndarray  # static line offsets (N, H, S)
    dn: np.ndarray  # ∂n w.r.t. own p, own v, other p, other v (N, H, A, 2, 8)
    drho: np.ndarray  # ∂ρ likewise (N, H, A, 8)
    dno: np.ndarray  # ∂n_o w.r.t. own p (N, H, S, 2, 2)
    drho_o: np.ndarray  # ∂ρ_o w.r.t. own p (N, H, S, 2)
    stat: np.ndarray  # stationarity residual (N, H, 2)
    c: np.ndarray  # primal constraints (N, H, R)
    lc: np.ndarray  # complementarity λ·c (N, H, R)
    robot: object  # the RobotView
    body: object  # the NearestBody of every (step, person)


class KktBlocks:
    """The local columns of every (k, j) block, shared by both KKT groups,
    and the derivatives at a point (computed once per point). Blocks exist
    for the T = ``pred.kkt_steps`` steps that embed the QP (T = N unless
    configured); the N below is that T.

    Local columns of block (k, j): a (2), λ (R), then the state: own p (2),
    own v (2), each human neighbour's p and v (4 each), the robot's
    configuration q_k (n: the base through the base line, every joint
    through the nearest-body line) and base velocities ν_base (nb). A column
    whose value is a constant of the step (v_0 of every human) maps to −1
    and is dropped."""

    def __init__(self, pred, layout):
        self.pred = pred
        self.layout = layout
        self.num_multipliers = pred.num_multipliers
        self.n = pred.robot.num_positions
        self.nb = NumBaseVelocities(pred.robot)
        self.ilam = 2
        self.io = 2 + self.num_multipliers  # own p, then own v
        self.inb = self.io + 4  # neighbour i: inb + 4i … inb + 4i + 3
        self.iq = self.inb + 4 * pred.num_neighbors
        self.inu = self.iq + self.n
        self.width = self.inu + self.nb
        # The base velocities that move the base in the plane (a holonomic
        # base's ω does not): the only ν columns a half-plane depends on.
        G, _ = VelocityMapPatterns(pred.robot)
        self.planar_nu = G[:2, : self.nb].any(axis=0)
        self.groups = []
        self._cache = None
        self.columns = self._Columns()

    def _Columns(self):
        """(N, H, width) global column of every local column (−1: constant)."""
        pred, layout = self.pred, self.layout
        N, H, K = pred.kkt_steps, pred.num_slots, pred.num_neighbors
        C = np.full((N, H, self.width), -1, dtype=int)
        C[:, :, 0:2] = pred.a[:N]
        C[:, :, self.ilam : self.ilam + self.num_multipliers] = pred.lam[:N]
        C[:, :, self.io : self.io + 2] = pred.p[:N]
        C[1:, :, self.io + 2 : self.io + 4] = pred.a[: N - 1]
        for i in range(K if pred.config.neighbor_derivatives else 0):
            other = pred.neighbors[:, i]
            c0 = self.inb + 4 * i
            C[:, :, c0 : c0 + 2] = pred.p[:N][:, other]
            C[1:, :, c0 + 2 : c0 + 4] = pred.a[: N - 1][:, other]
        C[:, :, self.iq : self.inu] = np.asarray(layout.q)[:N, None, :]
        C[:, :, self.inu :] = np.asarray(layout.nu)[:N, None, : self.nb]
        return C

    def UpdatePattern(self):
        """After the neighbour sets changed: new columns, new patterns."""
        self.columns = self._Columns()
        self._cache = None
        for group in self.groups:
            group.UpdatePattern()

    def Pattern(self, mask, rows_per_block, row_offset=0):
        """The structural nonzeros of ``mask`` (rows, width) in every block:
        (rows, cols, gather) with ``gather`` the flat index of each value in
        a dense (N, H, rows, width) array of local Jacobians."""
        N, H = self.pred.kkt_steps, self.pred.num_slots
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
        pred, K = self.pred, self.pred.num_neighbors
        J[:, :, rows, self.io : self.io + 4] += dX_own
        J[:, :, rows, self.inb : self.iq] += dX_other[..., :K, :].reshape(
            dX_other.shape[:3] + (4 * K,)
        )
        base, body = dX_other[..., K, :], dX_other[..., K + 1, :]  # (N,H,r,4)
        nearest = e.body
        J[:, :, rows, self.iq : self.iq + 2] += base[..., 0:2]
        J[:, :, rows, self.iq : self.inu] += np.einsum(
            "khri,khin->khrn", body[..., 0:2], nearest.d_dq
        )
        J[:, :, rows, self.io : self.io + 2] += np.einsum(
            "khri,khij->khrj", body[..., 0:2], nearest.d_dp
        )
        drv = base[..., 2:4] + body[..., 2:4]  # w.r.t. the base's velocity
        q, nu = e.robot.q, e.robot.nu
        N = pred.kkt_steps
        G = pred.robot.GStack(q[:N])[:, :2, : self.nb]
        dth = pred.robot.dGnu_dqStack(q[:N], nu[:N])[:, :2, 2]
        for k in range(N):
            J[k, :, rows, self.iq + 2] += drv[k] @ dth[k]
            J[k, :, rows, self.inu :] += drv[k] @ G[k]

    def Dimensions(self):
        """(T, H, A, R): the blocks' steps and people, agent lines per
        person and multipliers per person and step."""
        pred = self.pred
        return (
            pred.kkt_steps,
            pred.num_slots,
            pred.num_agent_lines,
            self.num_multipliers,
        )

    def EvaluateBlocks(self, point):
        """Evaluate(point) and the blocks' actions a (T, H, 2) and
        multipliers λ (T, H, R) at it."""
        T, z = self.pred.kkt_steps, point.z
        return self.Evaluate(point), z[self.pred.a[:T]], z[self.pred.lam[:T]]

    def Evaluate(self, point) -> "KktPointData":
        """Everything both groups need at a point, cached by the point."""
        if self._cache is not None and self._cache.point is point:
            return self._cache
        pred, layout = self.pred, self.layout
        z = point.z
        p, v, robot = pred.LocalState(z, layout, point.kin)
        planes, derivatives, body = pred.HalfPlaneDerivatives(p, v, robot)
        n, rho, no, rho_o = planes
        stat, c, lc = KktTerms(pred, z, v, n, rho, no, rho_o)
        self._cache = KktPointData(
            point, v, *planes, *derivatives, stat, c, lc, robot, body
        )
        return self._cache


class KktEqualities(ConstraintGroup):
    """Stationarity in a of every human's QP (eq. smith_kkt_stationarity)
    for the first T = kkt_steps steps, a held action a_k = a_{k−1} after
    them, and the human dynamics (eq. smith_humdyn), as = 0 rows."""

    name = "orca_kkt_equalities"

    def __init__(self, pred, blocks):
        self.pred = pred
        self.blocks = blocks
        N, H, T = pred.N, pred.num_slots, pred.kkt_steps
        self.num_kkt = T * H * 2
        num_hold = (N - T) * H * 2
        self.num_rows = self.num_kkt + num_hold + N * H * 2
        b = blocks
        # Stationarity component d depends on a_d (not the other component),
        # every λ and the whole local state (ν only where it moves the base).
        self.mask = np.ones((2, b.width), dtype=bool)
        self.mask[:, 0:2] = np.eye(2, dtype=bool)
        self.mask[:, b.inu :] = b.planar_nu
        # Held actions, per component: a_k, a_{k−1}; then the dynamics:
        # p_{k+1}, p_k, a_k.
        hold_rows = np.repeat(self.num_kkt + np.arange(num_hold), 2)
        hold_cols = np.stack([pred.a[T:].ravel(), pred.a[T - 1 : -1].ravel()], 1)
        dyn_rows = np.repeat(self.num_kkt + num_hold + np.arange(N * H * 2), 3)
        dyn_cols = np.stack(
            [pred.p[1:].ravel(), pred.p[:-1].ravel(), pred.a.ravel()], axis=1
        )
        self._dyn_rows = np.concatenate([hold_rows, dyn_rows])
        self._dyn_cols = np.concatenate([hold_cols.ravel(), dyn_cols.ravel()])
        self._dyn_vals = np.concatenate(
            [np.tile([1.0, -1.0], num_hold), np.tile([1.0, -1.0, -pred.dt], N * H * 2)]
        )
        blocks.groups.append(self)
        self.UpdatePattern()

    def UpdatePattern(self):
        rows, cols, self._gather = self.blocks.Pattern(self.mask, 2)
        self.rows = np.concatenate([rows, self._dyn_rows])
        self.cols = np.concatenate([cols, self._dyn_cols])

    def Eval(self, point):
        pred, b = self.pred, self.blocks
        e, a, lam = b.EvaluateBlocks(point)
        z = point.z
        N, H, A, R = b.Dimensions()
        v = e.v
        J = np.zeros((N, H, 2, b.width))
        eye = np.eye(2)
        J[:, :, :, 0:2] = (2 + 2 * lam[..., 0] + 2 * lam[..., 1])[..., None, None] * eye
        il = b.ilam
        J[:, :, :, il] = 2 * a
        J[:, :, :, il + 1] = 2 * (a - v)
        J[:, :, :, il + 2 : il + 2 + A] = -np.swapaxes(e.n, -1, -2)
        J[:, :, :, il + 2 + A : il + R] = -np.swapaxes(e.no, -1, -2)
        # −Σ λ_i ∂n_i/∂x − Σ λ_o ∂n_o/∂x, and −2λ_a ∂v/∂v_own.
        lam_i = lam[..., 2 : 2 + A]
        dn = e.dn  # (N, H, A, 2, 8)
        dX_own = -np.einsum("khi,khidx->khdx", lam_i, dn[..., :4])
        dX_own[..., 0:2] -= einsum("kho,khodx->khdx", lam[..., 2 + A :], e.dno)
        dX_own[..., 2:4] -= 2 * lam[..., 1, None, None] * eye
        dX_other = -np.einsum("khi,khidx->khdix", lam_i, dn[..., 4:])
        b.StateDerivatives(J, slice(0, 2), dX_own, dX_other, e)
        # Held actions a_k − a_{k−1}, dynamics p_{k+1} − p_k − Δt a_k.
        p, a_all = z[pred.p], z[pred.a]
        g_hold = a_all[N:] - a_all[N - 1 : -1]
        g_dyn = p[1:] - p[:-1] - pred.dt * a_all
        g = np.concatenate([e.stat.ravel(), g_hold.ravel(), g_dyn.ravel()])
        return g, np.concatenate([J.reshape(-1)[self._gather], self._dyn_vals])


class KktInequalities(ConstraintGroup):
    """Primal feasibility c ≤ 0 (eq. smith_kkt_primal) and relaxed
    complementarity λ·c ≥ −ε (eq. smith_kkt_complementarity) of every
    human's QP; dual feasibility λ ≥ 0 (eq. smith_kkt_dual) is a bound."""

    name = "orca_kkt_inequalities"
    lazy_setting = "lazy_line_margin"
    far_rows_in_small_qps = False

    def __init__(self, pred, blocks):
        self.pred = pred
        self.blocks = blocks
        N, H, A, K = (
            pred.kkt_steps,
            pred.num_slots,
            pred.num_agent_lines,
            pred.num_neighbors,
        )
        b, R = blocks, blocks.num_multipliers
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
                primal[r, b.inu :] = b.planar_nu
            else:  # the nearest body: all of q, ν_base
                primal[r, b.iq : b.inu] = True
                primal[r, b.inu :] = b.planar_nu
        primal[2 + A :, own_p] = True  # static lines: own position only
        self.mask = np.concatenate([primal, primal], axis=0)
        self.mask[R + np.arange(R), b.ilam + np.arange(R)] = True
        blocks.groups.append(self)
        self.UpdatePattern()

    def UpdatePattern(self):
        self.rows, self.cols, self._gather = self.blocks.Pattern(self.mask, self.ri)

    def Bounds(self, eps):
        R = self.blocks.num_multipliers
        lo = np.concatenate([np.full(R, -np.inf), np.full(R, -eps)])
        hi = np.concatenate([np.zeros(R), np.full(R, np.inf)])
        count = self.pred.kkt_steps * self.pred.num_slots
        return np.tile(lo, count), np.tile(hi, count)

    def _FarLines(self, point, margin):
        """The robot's two lines (the last agent lines: base, nearest body)
        as local row indices, and where each is inactive by more than
        ``margin`` (m/s, c < −margin) at ``point`` (N, H, 2)."""
        c = self.blocks.Evaluate(point).c
        lines = np.arange(2, 4) + self.pred.num_neighbors
        return lines, c[..., lines] < -margin

    def FarRows(self, point, margin):
        """The primal rows of a person's line of the robot's base or of its
        nearest body where that line is inactive by more than ``margin``
        (m/s) at ``point``. With their complementarity rows (FarEntries)
        they are the only rows that tie a person's prediction to the
        robot's configuration. Left out, the QP is a relaxation of the whole
        one; PiqpWorkspace.Solve checks them at its solution."""
        if margin <= 0 or self.num_rows == 0:
            return None
        lines, far = self._FarLines(point, margin)
        mask = np.zeros(far.shape[:2] + (self.ri,), dtype=bool)
        mask[..., lines] = far
        return mask.reshape(-1)

    def FarEntries(self, point, margin):
        """The entries λ̄ ∂c/∂(q, ν) of the complementarity rows of the
        lines FarRows leaves out (λ̄ is at most ε/margin there, if the point
        meets them): a sparse QP solver may solve them as zeros, which
        leaves the person's block without the robot's columns (an inexact
        Jacobian, as for the other people's states; the rows stay exact at
        the point)."""
        if margin <= 0 or self.num_rows == 0:
            return None
        lines, far = self._FarLines(point, margin)
        b, R = self.blocks, self.blocks.num_multipliers
        dense = np.zeros(far.shape[:2] + (self.ri, b.width), dtype=bool)
        dense[:, :, R + lines, b.iq :] = far[..., None]
        return dense.reshape(-1)[self._gather]

    def Eval(self, point):
        pred, b = self.pred, self.blocks
        e, a, lam = b.EvaluateBlocks(point)
        cfg = pred.config
        N, H, A, R = b.Dimensions()
        v, c = e.v, e.c
        il = b.ilam
        dc = np.zeros((N, H, R, b.width))
        dc[:, :, 0, 0:2] = 2 * a
        dc[:, :, 1, 0:2] = 2 * (a - v)
        dc[:, :, 1, il + 1] = -0.5 / cfg.slack_weight_acceleration
        dc[:, :, 1, b.io + 2 : b.io + 4] = -2 * (a - v)
        dc[:, :, 2 : 2 + A, 0:2] = -e.n
        dc[:, :, 2 + A :, 0:2] = -e.no
        dc[:, :, np.arange(2, 2 + A), il + np.arange(2, 2 + A)] = (
            -0.5 / cfg.slack_weight_velocity
        )
        # Agent line i: ∂(ρ_i − n_iᵀa)/∂x through its own and other state.
        dX = e.drho - np.einsum("khidx,khd->khix", e.dn, a)  # (N,H,A,8)
        dX_own = np.zeros((N, H, R, 4))
        dX_own[:, :, 2 : 2 + A] = dX[..., :4]
        dX_own[:, :, 2 + A :, 0:2] = e.drho_o - np.einsum("khodx,khd->khox", e.dno, a)
        dX_other = np.zeros((N, H, R, A, 4))
        dX_other[:, :, np.arange(2, 2 + A), np.arange(A)] = dX[..., 4:]
        b.StateDerivatives(dc, slice(0, R), dX_own, dX_other, e)
        # Complementarity λ_r c_r.
        dlc = lam[..., None] * dc
        dlc[:, :, np.arange(R), il + np.arange(R)] += c
        g = np.concatenate([c, e.lc], axis=-1)
        J = np.concatenate([dc, dlc], axis=2)
        return g.reshape(-1), J.reshape(-1)[self._gather]
