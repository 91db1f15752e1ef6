"""How far the people's lines of the robot are from binding in the bench
(the share of person-knots with both lines inactive by a margin):

    python line_slack.py ROBOT
"""

import sys

import numpy as np

from sm2ith_drake.control.prediction import kkt_groups as kg
from sm2ith_drake.run.bench import RunBenchmark

rec = []
orig = kg.KktInequalities.Eval


def Eval(self, point):
    out = orig(self, point)
    b = self.blocks
    e, a, lam = b.EvaluateBlocks(point)
    K = self.pred.num_neighbors
    rec.append((e.c[:, :, 2 + K : 4 + K].copy(), lam[:, :, 2 + K : 4 + K].copy()))
    return out


kg.KktInequalities.Eval = Eval
RunBenchmark(robot=sys.argv[1], humans=10, steps=60)
c = np.concatenate([r[0].ravel() for r in rec])
l = np.concatenate([r[1].ravel() for r in rec])
cmax = np.concatenate([r[0].max(-1).ravel() for r in rec])
print("robot-line c quantiles", np.quantile(c, [0.05, 0.25, 0.5, 0.75, 0.95, 0.99]))
for t in [0.1, 0.25, 0.5, 1.0]:
    print(f"person-knots with both robot lines c < -{t}: {np.mean(cmax < -t):.2f}")
print("lambda>1e-6 share", np.mean(l > 1e-6))
