"""Experiment, not in the product: the guard held for the base's stopping
time from its *current* speed (at least 3 steps) instead of its top speed,
the guard rows beyond it made trivial (the people out of reach), then
faithfulness_guarded.py's measurement (crossing_ridgeback_ur10_3h).

    python guard_current_speed.py 0-4
"""

import os

import numpy as np

from sm2ith_drake.control import cbf as cbf_mod
from sm2ith_drake.control import program as prog
from sm2ith_drake.control.cbf import _UNGUARDED
from sm2ith_drake.geometry import point_segment_distance_2d
from sm2ith_drake.robots.planar_base import NumBaseVelocities

VB = prog.MpcProgram.VariableBounds


def VariableBounds(self, q0, nu0):
    out = VB(self, q0, nu0)
    if self.cbf is not None and self.cbf.guard_steps:
        robot = self.robot
        axes = NumBaseVelocities(robot) - 1
        limit = np.asarray(robot.model.base_acceleration_limit, dtype=float)[:axes]
        t = float(np.max(np.abs(np.asarray(nu0)[:axes]) / limit))
        need = int(np.ceil(t / self.time_step - 1e-9))
        self.cbf._active_steps = max(BASE_STEPS, need)
    return out


prog.MpcProgram.VariableBounds = VariableBounds
GB = cbf_mod.DtCbfGroup._GuardBlock


def _GuardBlock(self, point, G, p0, v0, nearest=False):
    active = getattr(self, "_active_steps", None)
    if nearest or active is None or active >= G:
        return GB(self, point, G, p0, v0, nearest)
    # The original with the people out of reach after knot `active`.
    kin = point.kin
    ends = kin.capsule_points[: G + 1, :, :, :2]
    jac = kin.capsule_jacobians[: G + 1, :, :, :2, :]
    A, B = ends[:, None, :, 0], ends[:, None, :, 1]
    k = np.arange(G + 1)[:, None, None]
    P = p0[None] + k * self.guard_dt * v0[None]
    P[active + 1 :] = _UNGUARDED + 10.0 * np.arange(P.shape[1])[:, None]
    d, s, nrm = point_segment_distance_2d(A, B, P[:, :, None, :])
    h = d - self._human_offset
    JA, JB = jac[:, None, :, 0], jac[:, None, :, 1]
    Jc = (1 - s)[..., None, None] * JA + s[..., None, None] * JB
    dq = np.einsum("khci,khcin->khcn", nrm, Jc)
    a = self._Decay(h[:-1])
    g = h[1:] - a * h[:-1]
    a = a[..., None]
    vals = np.concatenate([-a * dq[:-1], dq[1:]], axis=3)
    return g.ravel(), vals.ravel()


cbf_mod.DtCbfGroup._GuardBlock = _GuardBlock
BASE_STEPS = 3
HERE = os.path.dirname(os.path.abspath(__file__))
with open(os.path.join(HERE, "faithfulness_guarded.py")) as f:
    exec(f.read())
