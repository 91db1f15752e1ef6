"""Compiled (numba) forward kinematics of a MobileManipulator's body steps:
the poses of the bodies, the world points fixed to them (end effector,
capsule ends) and those points' translational Jacobians, at K
configurations.

The tree is small (11–15 bodies) and a control step evaluates it a few
times for 1–11 configurations, so the cost of a vectorized numpy version
was its per-call overhead: 0.8 ms per call for 1 or 11 configurations,
3.7 ms per control instant with 3 people. This loop does the same
arithmetic per configuration and body. :class:`PackedSteps` lays the
BodySteps (robots/body_steps.py) out as arrays once; the numpy wrapper is
:meth:`MobileManipulator.CalcKinematics`, tested against MultibodyPlant
and finite differences.

``cache=True`` keeps the machine code next to this file, as
humans/kernels.py does.
"""

import numba
import numpy as np

from sm2ith_drake.robots.body_steps import PLANAR, PRISMATIC, REVOLUTE, WELD


class PackedSteps:
    """BodySteps as arrays, with the evaluated points (body slot and the
    point's position in that body's frame) and which plant positions move
    each point."""

    def __init__(
        self, steps, num_bodies, point_slots, point_local, ancestors, revolute_column
    ):
        self.num_bodies = int(num_bodies)
        self.body = np.array([st.body for st in steps], dtype=np.int64)
        self.parent = np.array([st.parent for st in steps], dtype=np.int64)
        self.kind = np.array([st.kind for st in steps], dtype=np.int64)
        self.column = np.array([st.column for st in steps], dtype=np.int64)
        self.R_PF = np.array([st.R_PF for st in steps], dtype=float).reshape(-1, 3, 3)
        self.p_PF = np.array([st.p_PF for st in steps], dtype=float).reshape(-1, 3)
        self.R_MC = np.array([st.R_MC for st in steps], dtype=float).reshape(-1, 3, 3)
        self.p_MC = np.array([st.p_MC for st in steps], dtype=float).reshape(-1, 3)
        self.axis_F = np.array([st.axis_F for st in steps], dtype=float).reshape(-1, 3)
        self.point_slots = np.ascontiguousarray(point_slots, dtype=np.int64)
        self.point_local = np.ascontiguousarray(point_local, dtype=float)
        self.point_mask = np.ascontiguousarray(ancestors[self.point_slots])
        self.revolute_column = np.ascontiguousarray(revolute_column)

    def Evaluate(self, qp: np.ndarray):
        """Points (K, P, 3), their Jacobians w.r.t. the plant positions
        (K, P, 3, n_plant) and the bodies' origins (K, bodies, 3) at the
        plant positions ``qp`` (K, n_plant)."""
        K, n_plant = qp.shape
        P = self.point_slots.size
        points = np.empty((K, P, 3))
        jac = np.zeros((K, P, 3, n_plant))
        origins = np.zeros((K, self.num_bodies, 3))
        forward_kinematics(
            np.ascontiguousarray(qp, dtype=float),
            self.body,
            self.parent,
            self.kind,
            self.column,
            self.R_PF,
            self.p_PF,
            self.R_MC,
            self.p_MC,
            self.axis_F,
            self.point_slots,
            self.point_local,
            self.point_mask,
            self.revolute_column,
            points,
            jac,
            origins,
        )
        return points, jac, origins


@numba.njit(cache=True)
def _Compose(R_A, p_A, R_B, p_B, R_out, p_out):  # pragma: no cover
    """(R_out, p_out) = (R_A, p_A) ∘ (R_B, p_B): R_A R_B, p_A + R_A p_B."""
    for i in range(3):
        acc = p_A[i]
        for j in range(3):
            acc += R_A[i, j] * p_B[j]
            s = 0.0
            for m in range(3):
                s += R_A[i, m] * R_B[m, j]
            R_out[i, j] = s
        p_out[i] = acc


@numba.njit(cache=True)
def forward_kinematics(  # pragma: no cover
    qp,
    body,
    parent,
    kind,
    column,
    R_PF,
    p_PF,
    R_MC,
    p_MC,
    axis_F,
    point_slots,
    point_local,
    point_mask,
    revolute_column,
    points,
    jac,
    origins,
):
    """Writes points, jac (zeroed by the caller) and origins; see
    PackedSteps.Evaluate. Per configuration: each step poses its body
    from its parent (frame F on the parent, the joint's motion F → M,
    then M → the body), recording every joint's world axis and a point on
    it; then each point and its Jacobian columns (ω × lever for a
    rotation, the axis for a translation)."""
    K, n_plant = qp.shape
    S = body.size
    B = origins.shape[1]
    R = np.empty((B, 3, 3))
    p = np.empty((B, 3))
    axes = np.zeros((n_plant, 3))
    through = np.zeros((n_plant, 3))
    R_WF = np.empty((3, 3))
    p_WF = np.empty(3)
    R_FM = np.empty((3, 3))
    p_FM = np.empty(3)
    R_WM = np.empty((3, 3))
    p_WM = np.empty(3)
    for k in range(K):
        for s in range(S):
            b, par, col = body[s], parent[s], column[s]
            if par < 0:
                R_WF[:, :] = R_PF[s]
                p_WF[:] = p_PF[s]
            else:
                _Compose(R[par], p[par], R_PF[s], p_PF[s], R_WF, p_WF)
            if kind[s] == WELD:
                R_WM[:, :] = R_WF
                p_WM[:] = p_WF
            elif kind[s] == REVOLUTE:
                # Rodrigues: R_FM = I + sin θ [a]× + (1 − cos θ) [a]×².
                a0, a1, a2 = axis_F[s, 0], axis_F[s, 1], axis_F[s, 2]
                st, ct = np.sin(qp[k, col]), np.cos(qp[k, col])
                v = 1.0 - ct
                R_FM[0, 0] = 1.0 + v * (-a1 * a1 - a2 * a2)
                R_FM[0, 1] = -st * a2 + v * a0 * a1
                R_FM[0, 2] = st * a1 + v * a0 * a2
                R_FM[1, 0] = st * a2 + v * a0 * a1
                R_FM[1, 1] = 1.0 + v * (-a0 * a0 - a2 * a2)
                R_FM[1, 2] = -st * a0 + v * a1 * a2
                R_FM[2, 0] = -st * a1 + v * a0 * a2
                R_FM[2, 1] = st * a0 + v * a1 * a2
                R_FM[2, 2] = 1.0 + v * (-a0 * a0 - a1 * a1)
                p_FM[:] = 0.0
                _Compose(R_WF, p_WF, R_FM, p_FM, R_WM, p_WM)
                for i in range(3):
                    axes[col, i] = R_WF[i, 0] * a0 + R_WF[i, 1] * a1 + R_WF[i, 2] * a2
                    through[col, i] = p_WF[i]
            elif kind[s] == PRISMATIC:
                R_WM[:, :] = R_WF
                for i in range(3):
                    w = (
                        R_WF[i, 0] * axis_F[s, 0]
                        + R_WF[i, 1] * axis_F[s, 1]
                        + R_WF[i, 2] * axis_F[s, 2]
                    )
                    axes[col, i] = w
                    p_WM[i] = p_WF[i] + w * qp[k, col]
            elif kind[s] == PLANAR:
                # (x, y, θ) in F, the world frame.
                st, ct = np.sin(qp[k, col + 2]), np.cos(qp[k, col + 2])
                R_FM[:, :] = 0.0
                R_FM[0, 0], R_FM[0, 1] = ct, -st
                R_FM[1, 0], R_FM[1, 1] = st, ct
                R_FM[2, 2] = 1.0
                p_FM[0], p_FM[1], p_FM[2] = qp[k, col], qp[k, col + 1], 0.0
                _Compose(R_WF, p_WF, R_FM, p_FM, R_WM, p_WM)
                for i in range(3):
                    for j in range(3):
                        axes[col + j, i] = R_WF[i, j]
                    through[col + 2, i] = p_WM[i]
            _Compose(R_WM, p_WM, R_MC[s], p_MC[s], R[b], p[b])
            origins[k, b, :] = p[b]
        for i in range(point_slots.size):
            b = point_slots[i]
            for r in range(3):
                points[k, i, r] = (
                    p[b, r]
                    + R[b, r, 0] * point_local[i, 0]
                    + R[b, r, 1] * point_local[i, 1]
                    + R[b, r, 2] * point_local[i, 2]
                )
            for j in range(n_plant):
                if not point_mask[i, j]:
                    continue
                if revolute_column[j]:
                    l0 = points[k, i, 0] - through[j, 0]
                    l1 = points[k, i, 1] - through[j, 1]
                    l2 = points[k, i, 2] - through[j, 2]
                    w0, w1, w2 = axes[j, 0], axes[j, 1], axes[j, 2]
                    jac[k, i, 0, j] = w1 * l2 - w2 * l1
                    jac[k, i, 1, j] = w2 * l0 - w0 * l2
                    jac[k, i, 2, j] = w0 * l1 - w1 * l0
                else:
                    for r in range(3):
                        jac[k, i, r, j] = axes[j, r]
