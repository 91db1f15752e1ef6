"""Task errors e(q) and their Jacobians (Section IV.A).

A task ℓ contributes J_ℓ = ½ Σ_k ‖e_ℓ,k‖²_{W_k} + ‖e_ℓ,N‖²_{W_N} to the cost of
its own stage and, in every lower stage, the lexicographic constraints
|e_ℓ,k,p| ≤ |e*_ℓ,k,p| (eq. stmpc_lex_constr). Every task here is a function of
the configuration q only, evaluated for K configurations at once from the
precomputed kinematics of the whole horizon.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from sm2ith_drake.robots.planar_base import NUM_BASE_POSITIONS
from sm2ith_drake.scenario import TaskConfig


class _Kinematics(Protocol):
    p_WE: np.ndarray  # (K, 3)
    J_WE: np.ndarray  # (K, 3, n)


# FacePoint's error fades out within this distance of its point (m).
FACE_POINT_RADIUS = 0.5


def WrapAngle(angle: np.ndarray) -> np.ndarray:
    """Wraps to [-π, π)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


class Task:
    """Base class: a named error e(q) ∈ R^s with weights.

    Subclasses implement :meth:`CalcErrorAndJacobian`. Custom tasks subclass
    this (see examples/custom_task.py).
    """

    def __init__(
        self,
        *,
        name: str,
        dim: int,
        target: np.ndarray,
        weight: np.ndarray | float = 1.0,
        terminal_weight: float = 5.0,
        weighted_sum_weight: float = 1.0,
        target_dim: int | None = None,
    ):
        """``target_dim``: the target's size when it is not the error's
        ``dim`` (e.g. a point to face)."""
        self.name = name
        self.dim = dim
        self.target = np.asarray(target, dtype=float).reshape(-1)
        size = dim if target_dim is None else target_dim
        if self.target.size != size:
            raise ValueError(
                f"task '{name}' needs a target of size {size}, got {self.target.size}"
            )
        w = np.broadcast_to(np.asarray(weight, dtype=float).reshape(-1), (dim,))
        self.weight = np.array(w)
        self.terminal_weight = float(terminal_weight)
        self.weighted_sum_weight = float(weighted_sum_weight)

    def JacobianPattern(self, num_positions: int) -> np.ndarray:
        """(dim, n) bool: the entries of ∂e/∂q that can be nonzero (all,
        unless a task knows better); the QPs keep only these."""
        return np.ones((self.dim, num_positions), dtype=bool)

    def CalcErrorAndJacobian(
        self, qs: np.ndarray, kin: _Kinematics, target: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Returns e (K, s) and de/dq (K, s, n) at the configurations qs (K, n)."""
        raise NotImplementedError

    def StageWeights(self, horizon: int) -> np.ndarray:
        """Diagonal weights for k = 1..N, shape (N, s); the last row is W_N."""
        w = np.tile(self.weight, (horizon, 1))
        w[-1] *= self.terminal_weight
        return w


class EePosition(Task):
    """e = p_WE(q) − p_target (world frame, 3D)."""

    def __init__(self, **kwargs):
        super().__init__(dim=3, **kwargs)

    def JacobianPattern(self, num_positions):
        # The planar base moves the EE in the plane: x not with y, y not
        # with x, and the height with none of (x, y, θ).
        pattern = super().JacobianPattern(num_positions)
        pattern[0, 1] = pattern[1, 0] = False
        pattern[2, :NUM_BASE_POSITIONS] = False
        return pattern

    def CalcErrorAndJacobian(self, qs, kin, target):
        return kin.p_WE - target, kin.J_WE


class _Selection(Task):
    """e = S q − target for a fixed selection of coordinates."""

    def __init__(self, *, indices, angle_components=(), num_positions, **kwargs):
        super().__init__(dim=len(indices), **kwargs)
        self._indices = np.asarray(indices)
        self._angles = list(angle_components)
        self._S = np.zeros((len(indices), num_positions))
        self._S[np.arange(len(indices)), self._indices] = 1.0

    def JacobianPattern(self, num_positions):
        return self._S != 0

    def CalcErrorAndJacobian(self, qs, kin, target):
        e = qs[:, self._indices] - target
        for p in self._angles:
            e[:, p] = WrapAngle(e[:, p])
        return e, np.broadcast_to(self._S, (qs.shape[0],) + self._S.shape)


class BasePosition(_Selection):
    """e = (x, y) − target; with ``offset`` d, the point d ahead along the
    base's x axis: e = (x + d cos θ, y + d sin θ) − target (TaskConfig.offset)."""

    def __init__(self, *, num_positions, offset: float = 0.0, **kwargs):
        super().__init__(indices=[0, 1], num_positions=num_positions, **kwargs)
        self.offset = float(offset)

    def JacobianPattern(self, num_positions):
        pattern = super().JacobianPattern(num_positions)
        pattern[:, 2] |= bool(self.offset)  # θ moves a point off the origin
        return pattern

    def CalcErrorAndJacobian(self, qs, kin, target):
        if not self.offset:
            return super().CalcErrorAndJacobian(qs, kin, target)
        c, s = np.cos(qs[:, 2]), np.sin(qs[:, 2])
        e = qs[:, :2] - target
        e[:, 0] += self.offset * c
        e[:, 1] += self.offset * s
        J = np.repeat(self._S[None], qs.shape[0], axis=0)  # ∂(x, y)/∂q
        J[:, 0, 2] = -self.offset * s
        J[:, 1, 2] = self.offset * c
        return e, J


class BasePose(_Selection):
    """e = (x, y, θ) − target, θ wrapped to [−π, π)."""

    def __init__(self, *, num_positions, **kwargs):
        super().__init__(
            indices=[0, 1, 2],
            angle_components=[2],
            num_positions=num_positions,
            **kwargs,
        )


class FacePoint(Task):
    """e = w(r) · wrap(θ − atan2(t_y − y, t_x − x)): the base turned to face
    the target point t (a differential drive moves along its heading), with
    w(r) = min(1, r / FACE_POINT_RADIUS) fading the error out within that
    distance r of the point, so the base does not spin where the bearing is
    undefined."""

    def __init__(self, **kwargs):
        super().__init__(dim=1, target_dim=2, **kwargs)

    def JacobianPattern(self, num_positions):
        pattern = np.zeros((1, num_positions), dtype=bool)
        pattern[0, :NUM_BASE_POSITIONS] = True
        return pattern

    def CalcErrorAndJacobian(self, qs, kin, target):
        d = np.asarray(target, dtype=float)[None] - qs[:, :2]  # (K, 2)
        r2 = np.maximum(np.sum(d * d, axis=1), 1e-12)
        r = np.sqrt(r2)
        a = WrapAngle(qs[:, 2] - np.arctan2(d[:, 1], d[:, 0]))
        inside = r < FACE_POINT_RADIUS
        w = np.where(inside, r / FACE_POINT_RADIUS, 1.0)
        # ∂a/∂(x, y) = (−d_y, d_x) / r², ∂a/∂θ = 1; ∂w/∂(x, y) = −d / (r R)
        # inside the radius, 0 outside.
        da = np.stack([-d[:, 1], d[:, 0]], axis=1) / r2[:, None]
        dw = np.where(inside[:, None], -d / (r * FACE_POINT_RADIUS)[:, None], 0.0)
        J = np.zeros((qs.shape[0], 1, qs.shape[1]))
        J[:, 0, :2] = w[:, None] * da + a[:, None] * dw
        J[:, 0, 2] = w
        return (w * a)[:, None], J


class JointPosture(_Selection):
    """e = q_arm − target (all non-base coordinates)."""

    def __init__(self, *, num_positions, **kwargs):
        super().__init__(
            indices=list(range(NUM_BASE_POSITIONS, num_positions)),
            num_positions=num_positions,
            **kwargs,
        )


class EePositionInBase(Task):
    """e = R_z(θ)ᵀ (p_WE − (x, y, 0)) − target: the EE held at a point of the
    base frame (the paper's "arm extended away from the base" task)."""

    def __init__(self, **kwargs):
        super().__init__(dim=3, **kwargs)

    def CalcErrorAndJacobian(self, qs, kin, target):
        K = qs.shape[0]
        c, s = np.cos(qs[:, 2]), np.sin(qs[:, 2])
        d = kin.p_WE.copy()
        d[:, 0] -= qs[:, 0]
        d[:, 1] -= qs[:, 1]
        # R_z(θ)ᵀ d, written out per configuration.
        e = np.empty((K, 3))
        e[:, 0] = c * d[:, 0] + s * d[:, 1]
        e[:, 1] = -s * d[:, 0] + c * d[:, 1]
        e[:, 2] = d[:, 2]
        dd = kin.J_WE.copy()
        dd[:, 0, 0] -= 1.0
        dd[:, 1, 1] -= 1.0
        J = np.empty_like(dd)
        J[:, 0] = c[:, None] * dd[:, 0] + s[:, None] * dd[:, 1]
        J[:, 1] = -s[:, None] * dd[:, 0] + c[:, None] * dd[:, 1]
        J[:, 2] = dd[:, 2]
        # ∂(R_zᵀ)/∂θ d.
        J[:, 0, 2] += -s * d[:, 0] + c * d[:, 1]
        J[:, 1, 2] += -c * d[:, 0] - s * d[:, 1]
        return e - target, J


def MakeTask(config: TaskConfig, num_positions: int) -> Task:
    """Builds a task from its scenario config."""
    kwargs = dict(
        name=config.name or config.kind,
        target=np.asarray(config.target, dtype=float),
        weight=np.asarray(config.weight if config.weight else [1.0], dtype=float),
        terminal_weight=config.terminal_weight,
        weighted_sum_weight=config.weighted_sum_weight,
    )
    if config.kind == "ee_position":
        return EePosition(**kwargs)
    if config.kind == "ee_position_in_base":
        return EePositionInBase(**kwargs)
    if config.kind == "base_position":
        return BasePosition(num_positions=num_positions, offset=config.offset, **kwargs)
    if config.kind == "base_pose":
        return BasePose(num_positions=num_positions, **kwargs)
    if config.kind == "joint_posture":
        return JointPosture(num_positions=num_positions, **kwargs)
    if config.kind == "face_point":
        return FacePoint(**kwargs)
    raise ValueError(f"unknown task kind '{config.kind}'")
