"""Whole-body DT-CBF collision avoidance (eq. smith_avoid_coll).

For every robot capsule c (the base and every arm link) and every human j:

    h_{k,j,c} = dist_xy(capsule c at q_k, human j at p_{k,j}) − r_c − r_h − margin,

the horizontal distance between the capsule's axis projected on the floor and
the human's centre, so a human is a vertical cylinder taller than the robot
(conservative for an arm above a head). Static obstacles are wall segments
(polygons are their edges), treated the same way. The constraints

    h(x_{k+1}) − (1 − γ) h(x_k) ≥ 0,   k = 0 … N − 1,

bound how fast the robot may approach the boundary of the safe set h ≥ 0 and
keep it forward invariant. The human positions p_{k,j} are decision
variables: fixed by bounds for the CVMM and React predictors, free (and
coupled through the ORCA KKT system) for SM²ITH.
"""

import numpy as np

from sm2ith_drake.control.groups import BlockPattern, ConstraintGroup
from sm2ith_drake.geometry import point_segment_distance_2d, segment_closest_points

_EPS = 1e-9


def _Lift(x):
    """Planar points (..., 2) as points on the floor (..., 3)."""
    return np.concatenate([x, np.zeros(x.shape[:-1] + (1,))], axis=-1)


def ObstacleSegments(obstacles) -> np.ndarray:
    """(S, 2, 2) wall segments of ObstacleConfigs (polygons: every edge)."""
    segments = []
    for o in obstacles:
        v = np.asarray(o.vertices, dtype=float)
        edges = [v] if len(v) == 2 else np.stack([v, np.roll(v, -1, 0)], axis=1)
        segments.extend(edges)
    return np.array(segments).reshape(-1, 2, 2)


# Where the guard rows put a human they do not hold (m): out of reach.
_UNGUARDED = np.array([1.0e4, 1.0e4])
# The value of a near row whose person is not near (it holds trivially).
_FAR_ROW = 1.0e3


def _OutOfReach(positions, held):
    """The positions with every human not ``held`` (None: all are) moved out
    of reach (each to its own far point)."""
    p = np.array(positions, dtype=float).reshape(-1, 2)
    if held is not None:
        off = ~np.asarray(held, dtype=bool)
        p[off] = _UNGUARDED + 10.0 * np.arange(len(p))[off, None]
    return p


class DtCbfGroup(ConstraintGroup):
    """h_{k+1} − (1 − γ) h_k ≥ 0 for robot capsules vs. humans and walls.

    Rows are k-major: for each k, first H × C human rows (human-major), then
    S × C obstacle rows. With ``guard_steps`` = G > 0, G × H × C more rows
    hold the first G steps against each human moving on at its *measured*
    velocity (``SetGuard``), whatever the predictor expects the human to do:
    an interactive prediction may count on a person giving way, but the robot
    never closes in on one who does not faster than the barrier allows. More
    than one step matters for a robot with inertia: a guard on the first step
    alone lets the plan build up speed toward a person in the later steps
    that the next first step can no longer brake. With ``static_guard_steps``
    = G_s > 0, G_s × H × C more rows (after those) hold the first G_s steps
    against each human standing still where measured: a prediction (CVMM's
    or SM²ITH's) that has a person move away never lets the robot close in
    on where they are now faster than the barrier allows, so the robot does
    not follow someone out of its margin into contact. With
    ``extra_humans`` = E > 0, N × E × C more rows (last) hold the whole
    horizon against up to E people who have no slot in the program (more
    people than ``max_humans``), each moving on at its measured velocity
    (``SetExtra``): they are not predicted interactively, but the robot
    keeps out of their way as CVMM would. An extra person has one row per
    step, on the robot's nearest capsule at the linearization point (h of
    the whole robot is the minimum over its capsules), not one per capsule:
    a sixth of the rows. With ``near_steps`` = G_n > 0 and ``near_gap`` > 0,
    G_n × H more rows (after the extra ones) hold every person measured
    within ``near_gap`` (surface to surface) of the robot's nearest body no
    closer where they stand: the nearest capsule's h_{k+1} ≥ h_k
    (SafetyConfig.no_closer_gap); ``near_rows`` are their indices.
    """

    name = "dt_cbf"

    def __init__(
        self,
        robot,
        layout,
        human_positions,
        *,
        gamma,
        human_radius,
        human_margin,
        obstacle_segments,
        obstacle_margin,
        guard_steps=0,
        static_guard_steps=0,
        extra_humans=0,
        inside="decay",
        guard_gamma=None,
        guard_inside="exit",
        near_steps=0,
        near_gap=0.0,
        near_speed=0.0,
    ):
        if inside not in ("decay", "exit"):
            raise ValueError(f"inside must be 'decay' or 'exit', not {inside!r}")
        if guard_inside not in ("exit", "hold"):
            raise ValueError(
                f"guard_inside must be 'exit' or 'hold', not {guard_inside!r}"
            )
        self.inside = inside
        self.guard_inside = guard_inside
        self._robot = robot
        self._layout = layout
        N = layout.N
        self._P = np.asarray(human_positions).reshape(N + 1, -1, 2)
        H = self._P.shape[1]
        C = len(robot.capsules)
        self._segments = np.asarray(obstacle_segments, dtype=float).reshape(-1, 2, 2)
        S = len(self._segments)
        self._H, self._C, self._S = H, C, S
        self.gamma = float(gamma)
        # The moving guard's γ (None or 0, SafetyConfig's default: gamma).
        self.guard_gamma = float(guard_gamma) if guard_gamma else self.gamma
        self._human_offset = robot.capsule_radii[None, :] + human_radius + human_margin
        self._human_margin = float(human_margin)
        self._obstacle_offset = robot.capsule_radii[None, :] + obstacle_margin
        self.rows_per_step = (H + S) * C
        self.guard_steps = int(min(max(guard_steps, 0), N))
        self.static_guard_steps = int(min(max(static_guard_steps, 0), N))
        E = self.num_extra = int(max(extra_humans, 0))
        self.near_gap = float(near_gap)
        # SafetyConfig.no_closer_speed (m/s): > 0, only slower people near.
        self.near_speed = float(near_speed)
        near_steps = int(min(max(near_steps, 0), N)) if self.near_gap > 0 else 0
        # Guard row blocks, in row order: (steps, people, which guard).
        self._guards = [
            (self.guard_steps, H * C, "moving"),
            (self.static_guard_steps, H * C, "static"),
            (N if E else 0, E, "extra"),
            (near_steps, H, "near"),
        ]
        self.num_guard = sum(steps * per_step for steps, per_step, _ in self._guards)
        self.num_rows = N * self.rows_per_step + self.num_guard
        self.near_rows = np.arange(self.num_rows - near_steps * H, self.num_rows)
        self.guard_p0 = np.zeros((H, 2))
        self.guard_v0 = np.zeros((H, 2))
        self.static_p0 = np.zeros((H, 2))
        self.static_speed = np.zeros(H)
        self.extra_p0 = _OutOfReach(np.zeros((E, 2)), np.zeros(E, dtype=bool))
        self.extra_v0 = np.zeros((E, 2))
        self.guard_dt = 0.0
        row_blocks, col_blocks = [], []
        for k in range(N):
            base = k * self.rows_per_step
            for j in range(H):
                for c in range(C):
                    row_blocks.append(np.array([base + j * C + c]))
                    col_blocks.append(
                        np.concatenate(
                            [
                                layout.q[k],
                                layout.q[k + 1],
                                self._P[k, j],
                                self._P[k + 1, j],
                            ]
                        )
                    )
            for s in range(S):
                for c in range(C):
                    row_blocks.append(np.array([base + H * C + s * C + c]))
                    col_blocks.append(np.concatenate([layout.q[k], layout.q[k + 1]]))
        row = N * self.rows_per_step
        for steps, per_step, _ in self._guards:
            for r in range(steps * per_step):
                k = r // per_step
                row_blocks.append(np.array([row + r]))
                col_blocks.append(np.concatenate([layout.q[k], layout.q[k + 1]]))
            row += steps * per_step
        self.person_rows = self._PersonRows()
        # One slack per row under an exact penalty (MpcProgram): zero
        # whenever the hard constraints can be met; when they cannot (a person
        # walking into the robot faster than it can get away), the robot does
        # the best it can instead of losing its plan.
        self.slack = layout.AddVariables("cbf_slack", (self.num_rows,))
        # The rows (and slacks) that keep the robot off the walls.
        per_step = np.arange(H * C, self.rows_per_step)
        self.obstacle_rows = (
            np.arange(N)[:, None] * self.rows_per_step + per_step[None]
        ).ravel()
        if row_blocks:
            self.rows, self.cols = BlockPattern(row_blocks, col_blocks)
            self.rows = np.concatenate([self.rows, np.arange(self.num_rows)])
            self.cols = np.concatenate([self.cols, self.slack])
            self.KeepStructuralNonzeros(self._StructuralMask(robot.capsule_joint_masks))
        else:
            self.rows = self.cols = np.zeros(0, dtype=int)

    def _PersonRows(self):
        """(H, ·) each slot's horizon and moving and static guard rows."""
        N, H, C, R = self._layout.N, self._H, self._C, self.rows_per_step
        slot = np.arange(H)[:, None, None] * C + np.arange(C)[None, None, :]
        rows, row = [slot + np.arange(N)[None, :, None] * R], N * R
        for steps, per_step, which in self._guards:
            if which in ("moving", "static"):
                rows.append(row + slot + np.arange(steps)[None, :, None] * H * C)
            row += steps * per_step
        return np.concatenate([r.reshape(H, r.shape[1] * C) for r in rows], axis=1)

    def _StructuralMask(self, capsule_masks):
        """The pattern entries that can be nonzero: a capsule's barrier moves
        only with the joints that move the capsule (``capsule_masks`` (C, n))."""
        N, H, S = self._layout.N, self._H, self._S
        qq = np.concatenate([capsule_masks, capsule_masks], axis=1)  # (C, 2n)
        C = qq.shape[0]
        human = np.concatenate([qq, np.ones((C, 4), dtype=bool)], axis=1)
        step = np.concatenate(
            [
                np.broadcast_to(human, (H,) + human.shape).ravel(),
                np.broadcast_to(qq, (S,) + qq.shape).ravel(),
            ]
        )
        guard = [
            # An extra or near person's row is on whichever capsule is nearest.
            np.broadcast_to(qq.any(axis=0), (steps * per_step, qq.shape[1])).ravel()
            if which in ("extra", "near")
            else np.broadcast_to(qq, (steps * per_step // C,) + qq.shape).ravel()
            for steps, per_step, which in self._guards
        ]
        return np.concatenate(
            [np.tile(step, N), *guard, np.ones(self.num_rows, dtype=bool)]
        )

    def SetGuard(self, positions, velocities, time_step, guarded=None, active=None):
        """The measured humans for the guard rows; a human not ``guarded``
        (H,) bool (default: all are) is moved out of reach of the moving
        guard's rows, one not ``active`` (default: all are) out of reach of
        the static guard's, so their rows hold trivially (the QP's pattern
        stays)."""
        p = np.array(positions, dtype=float).reshape(-1, 2)
        v = np.array(velocities, dtype=float).reshape(-1, 2)
        self.static_p0 = _OutOfReach(p, active)
        self.static_speed = np.linalg.norm(v, axis=1)  # measured, before the guard's
        if guarded is not None:
            v[~np.asarray(guarded, dtype=bool)] = 0.0
        self.guard_p0, self.guard_v0 = _OutOfReach(p, guarded), v
        self.guard_dt = float(time_step)

    def SetExtra(self, positions, velocities, time_step, active):
        """The people without a slot for the extra rows, (E, 2) each; one
        not ``active`` (E,) bool is moved out of reach (its rows hold
        trivially, the QP's pattern stays)."""
        self.extra_p0 = _OutOfReach(positions, active)
        self.extra_v0 = np.array(velocities, dtype=float).reshape(-1, 2)
        self.extra_v0[~np.asarray(active, dtype=bool)] = 0.0
        self.guard_dt = float(time_step)

    def _GuardRows(self, point):
        """Every guard block's rows (moving, static, extra) and values."""
        g, vals = [], []
        for steps, _, which in self._guards:
            if steps and which == "near":
                gi, vi = self._NearBlock(point, steps)
                g.append(gi)
                vals.append(vi)
            elif steps:
                p0, v0 = {
                    "moving": (self.guard_p0, self.guard_v0),
                    "static": (self.static_p0, np.zeros_like(self.static_p0)),
                    "extra": (self.extra_p0, self.extra_v0),
                }[which]
                moving = which == "moving"
                gi, vi = self._GuardBlock(
                    point,
                    steps,
                    p0,
                    v0,
                    which == "extra",
                    gamma=self.guard_gamma if moving else None,
                    hold=moving and self.guard_inside == "hold",
                )
                g.append(gi)
                vals.append(vi)
        return np.concatenate(g), np.concatenate(vals)

    def _GuardBlock(
        self, point, G, p0, v0, nearest=False, gamma=None, hold=False, with_h=False
    ):
        """h(q_{k+1}, p0 + (k+1)Δt v0) − (1 − γ) h(q_k, p0 + kΔt v0) for
        k < G, and their q_k, q_{k+1} gradients: per capsule, or with
        ``nearest`` of the whole robot (the nearest capsule at each knot);
        ``gamma`` replaces γ (None: the barrier's). With ``hold``, a row
        whose h_k < 0 at the linearization point (the robot already inside
        the margin of the person moving on) is h_{k+1} − h_k ≥ 0 instead:
        no closer, rather than out at once (SafetyConfig.guard_inside). With
        ``with_h``, h at the knots 0 … G, (G+1, H, C or 1), is returned too."""
        kin = point.kin
        ends = kin.capsule_points[: G + 1, :, :, :2]  # knots 0 … G
        jac = kin.capsule_jacobians[: G + 1, :, :, :2, :]
        A, B = ends[:, None, :, 0], ends[:, None, :, 1]  # (G+1, 1, C, 2)
        k = np.arange(G + 1)[:, None, None]
        P = p0[None] + k * self.guard_dt * v0[None]
        d, s, nrm = point_segment_distance_2d(A, B, P[:, :, None, :])  # (G+1, H, C)
        h = d - self._human_offset
        JA, JB = jac[:, None, :, 0], jac[:, None, :, 1]
        Jc = (1 - s)[..., None, None] * JA + s[..., None, None] * JB
        dq = np.einsum("khci,khcin->khcn", nrm, Jc)  # (G+1, H, C, n)
        if nearest:
            c = np.argmin(h, axis=2)[..., None]  # (G+1, H, 1)
            h = np.take_along_axis(h, c, axis=2)
            dq = np.take_along_axis(dq, c[..., None], axis=2)
        a = self._Decay(h[:-1], gamma)
        if hold:
            a = np.where(h[:-1] < 0, 1.0, a)
        g = h[1:] - a * h[:-1]  # (G, H, C or 1)
        a = a[..., None]
        vals = np.concatenate([-a * dq[:-1], dq[1:]], axis=3)  # (G, H, ·, 2n)
        if with_h:
            return g.ravel(), vals.ravel(), h
        return g.ravel(), vals.ravel()

    def _NearBlock(self, point, G):
        """The rows h_{k+1} − h_k ≥ 0 of the nearest capsule against each
        person standing where measured (``static_p0``), k < G; a person not
        within ``near_gap`` of the robot at knot 0 (the measured
        configuration), or with ``near_speed`` > 0 measured at least that
        fast, has rows that hold trivially."""
        p0 = self.static_p0
        g, vals, h = self._GuardBlock(
            point,
            G,
            p0,
            np.zeros_like(p0),
            nearest=True,
            gamma=0.0,
            hold=True,
            with_h=True,
        )
        gap = h[0, :, 0] + self._human_margin  # the nearest body's, at knot 0
        far = gap >= self.near_gap
        if self.near_speed > 0:
            far = far | (self.static_speed >= self.near_speed)
        far = np.broadcast_to(far, (G, len(p0)))
        g = np.where(far.ravel(), _FAR_ROW, g)
        vals = vals.reshape(G, len(p0), -1)
        vals[far] = 0.0
        return g, vals.ravel()

    def _Decay(self, h, gamma=None):
        """The factor (1 − γ) of h_k in each row h_{k+1} − (1 − γ) h_k ≥ 0,
        given h_k at the linearization point. With ``inside`` "exit", 0
        where h_k < 0: a row whose barrier is already violated asks for
        h_{k+1} ≥ 0, so its slack measures how deep the plan is at k + 1
        rather than how fast it goes deeper (the rows are the same wherever
        h ≥ 0, so this only changes plans that need slack)."""
        decay = 1.0 - (self.gamma if gamma is None else gamma)
        if self.inside != "exit":
            # One factor for every row (a 0-d array: it broadcasts as the
            # full one would, without one allocated per evaluation).
            return np.asarray(decay)
        return np.where(h < 0, 0.0, decay)

    def Barriers(self, point):
        """h at every knot: humans (K, H, C) and obstacles (K, S, C), with
        their gradients w.r.t. q (K, ·, C, n) and the human positions
        (K, H, C, 2)."""
        jac = point.kin.capsule_jacobians[..., :2, :]  # (K, C, 2, 2, n)
        A, B, (d, s, nrm) = self._HumanDistances(point)  # d: (K, H, C)
        h_hum = d - self._human_offset
        JA, JB = jac[:, None, :, 0], jac[:, None, :, 1]  # (K, 1, C, 2, n)
        Jc = (1 - s)[..., None, None] * JA + s[..., None, None] * JB
        dh_dq_hum = np.einsum("khci,khcin->khcn", nrm, Jc)
        dh_dp = -nrm
        if self._S:
            W = self._segments  # (S, 2, 2)
            sa, _, c1, c2 = segment_closest_points(
                _Lift(A),
                _Lift(B),
                _Lift(W[None, :, None, 0]),
                _Lift(W[None, :, None, 1]),
            )
            diff = (c1 - c2)[..., :2]
            dist = np.linalg.norm(diff, axis=-1)  # (K, S, C)
            nrm_o = diff / np.maximum(dist, _EPS)[..., None]
            h_obs = dist - self._obstacle_offset
            Jo = (1 - sa)[..., None, None] * JA + sa[..., None, None] * JB
            dh_dq_obs = np.einsum("ksci,kscin->kscn", nrm_o, Jo)
        else:
            K, C, n = jac.shape[0], self._C, jac.shape[-1]
            h_obs = np.zeros((K, 0, C))
            dh_dq_obs = np.zeros((K, 0, C, n))
        return h_hum, dh_dq_hum, dh_dp, h_obs, dh_dq_obs

    def _HumanDistances(self, point):
        """The capsules' floor-plane axes A, B (K, 1, C, 2) and
        point_segment_distance_2d of every predicted human to them (d, s,
        n: (K, H, C) …)."""
        ends = point.kin.capsule_points[..., :2]  # (K, C, 2, 2)
        A, B = ends[:, None, :, 0], ends[:, None, :, 1]
        P = point.z[self._P][:, :, None, :]  # (K, H, 1, 2)
        return A, B, point_segment_distance_2d(A, B, P)

    def FarRows(self, point, distance):
        """The predicted-human rows whose body and person are more than
        ``distance`` (m, surface to margin: h) apart at both knots of the row
        at ``point``; the walls' and guards' rows are never far (they do not
        couple the people's variables to the robot's)."""
        if distance <= 0 or self.num_rows == 0 or self._H == 0:
            return None
        d = self._HumanDistances(point)[2][0]
        far = (d - self._human_offset) > distance  # (K, H, C)
        N = self._layout.N
        rows = np.zeros((N, self.rows_per_step), dtype=bool)
        rows[:, : self._H * self._C] = (far[:-1] & far[1:]).reshape(N, -1)
        mask = np.zeros(self.num_rows, dtype=bool)
        mask[: N * self.rows_per_step] = rows.ravel()
        return mask

    def Eval(self, point):
        N = self._layout.N
        if self.num_rows == 0:
            return np.zeros(0), np.zeros(0)
        h_hum, dq_hum, dp, h_obs, dq_obs = self.Barriers(point)
        a_hum, a_obs = self._Decay(h_hum[:-1]), self._Decay(h_obs[:-1])
        g_hum = h_hum[1:] - a_hum * h_hum[:-1]  # (N, H, C)
        g_obs = h_obs[1:] - a_obs * h_obs[:-1]  # (N, S, C)
        g = np.concatenate([g_hum.reshape(N, -1), g_obs.reshape(N, -1)], axis=1)
        # Jacobian blocks in the pattern's order.
        a_hum, a_obs = a_hum[..., None], a_obs[..., None]
        hum = np.concatenate(
            [-a_hum * dq_hum[:-1], dq_hum[1:], -a_hum * dp[:-1], dp[1:]], axis=3
        )  # (N, H, C, 2n + 4)
        # (N, S, C, 2n)
        obs = np.concatenate([-a_obs * dq_obs[:-1], dq_obs[1:]], axis=3)
        vals = np.concatenate([hum.reshape(N, -1), obs.reshape(N, -1)], axis=1)
        g, vals = g.ravel(), vals.ravel()
        if self.num_guard:
            g_guard, vals_guard = self._GuardRows(point)
            g = np.concatenate([g, g_guard])
            vals = np.concatenate([vals, vals_guard])
        vals = np.concatenate([vals, np.ones(self.num_rows)])
        return g + point.z[self.slack], self.Structural(vals)
