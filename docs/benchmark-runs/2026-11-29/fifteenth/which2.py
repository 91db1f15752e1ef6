"""Which far DT-CBF rows the 10-person bench puts back (README, The
10-person p99, fifteenth session): their values at the linearization
point, how many would be kept in by a threshold on the row's value, and
how pass 2's put-backs overlap pass 1's. Not a controller.

    python which2.py ROBOT STEPS"""

import sys

import numpy as np

from sm2ith_drake.control import cbf, hierarchy
from sm2ith_drake.run import bench

records = []
step = [0]
far_rows = cbf.DtCbfGroup.FarRows


def FarRows(self, point, distance):
    mask = far_rows(self, point, distance)
    if mask is not None:
        h = self._HumanDistances(point)[2][0] - self._human_offset  # (K, H, C)
        records.append((step[0], mask, mask.copy(), h, self))
    return mask


step_solve = hierarchy.HierarchicalSolver.Solve


def StepSolve(self, *args, **kwargs):
    result = step_solve(self, *args, **kwargs)
    step[0] += 1
    return result


def HumanRows(group, mask):
    N, H, C = group._layout.N, group._H, group._C
    rows = mask[: N * group.rows_per_step].reshape(N, group.rows_per_step)
    return rows[:, : H * C].reshape(N, H, C)


cbf.DtCbfGroup.FarRows = FarRows
hierarchy.HierarchicalSolver.Solve = StepSolve
bench.RunBenchmark(robot=sys.argv[1], humans=10, steps=int(sys.argv[2]))

put_back, lazy, points = [], [], []
for s, mask, first, h, group in records:
    value = h[1:] - 0.7 * h[:-1]  # the row's value at the point (N, H, C)
    left_out, back = HumanRows(group, first), HumanRows(group, first & ~mask)
    lazy.append(value[left_out])
    put_back.append(np.stack([value[back], h[:-1][back]], axis=1))
    if back.any():
        points.append((s, value[back].max()))
lazy, put_back = np.concatenate(lazy), np.concatenate(put_back)
print("rows left out", lazy.size, "put back", len(put_back))
quantiles = [0, 0.1, 0.5, 0.9, 1]
print("value at the point, put back:", np.quantile(put_back[:, 0], quantiles).round(3))
print("value at the point, left out:", np.quantile(lazy, quantiles).round(3))
print("h at the point, put back:", np.quantile(put_back[:, 1], quantiles).round(2))
for t in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4):
    print(
        f"value threshold {t}: {np.mean(lazy < t) * 100:.1f} % of the rows left "
        f"out kept in, {np.mean(put_back[:, 0] < t) * 100:.1f} % of the put-backs"
    )
points = np.array(points)
print("points with a put-back", len(points), "of", len(records))
for t in (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5):
    print(t, "points with every put-back kept in", int((points[:, 1] < t).sum()))
print("steps", points[:, 0].astype(int))
print("overlap of pass 2's put-backs with pass 1's")
by_step = {}
for s, mask, first, _, _ in records:
    by_step.setdefault(s, []).append((first & ~mask, first))
for s, passes in sorted(by_step.items()):
    if len(passes) == 2 and passes[1][0].any():
        (p1, left1), (p2, _) = passes
        both, new = int((p1 & p2).sum()), int((p2 & left1 & ~p1).sum())
        print(
            s,
            f"pass 1 {int(p1.sum())}, pass 2 {int(p2.sum())}, both {both},"
            f" pass 2's left out in pass 1 and not put back {new}",
        )
