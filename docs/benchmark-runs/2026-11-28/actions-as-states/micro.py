import sys, time, numpy as np
from sm2ith_drake.control import hpipm_stage_qp
from sm2ith_drake.run.bench import BenchmarkScenario, _Simulate
calls = []
orig = hpipm_stage_qp.HpipmStageQp.Solve
def rec(self, *a, **k):
    calls.append((self, a, dict(k)))
    return orig(self, *a, **k)
hpipm_stage_qp.HpipmStageQp.Solve = rec
robot = sys.argv[1]; H = int(sys.argv[2])
sc = BenchmarkScenario(robot, H, "orca_kkt", "rti", None, "")
_Simulate(sc, 60)
hpipm_stage_qp.HpipmStageQp.Solve = orig
import gc; gc.disable()
tot=[]; its=[]
for idx in range(len(calls) - 40, len(calls)):
    s, a, k = calls[idx]
    k = dict(k); k["warm_token"] = None
    best = 1e9
    for r in range(15):
        t = time.perf_counter(); z, st, it = s.Solve(*a, **k); best = min(best, time.perf_counter() - t)
    tot.append(best * 1e3); its.append(it)
tot = np.array(tot); its = np.array(its)
print("per QP min-of-15 ms: mean %.3f median %.3f; iterations mean %.1f; ms/iter %.4f" % (tot.mean(), np.median(tot), its.mean(), (tot / its).mean()))
