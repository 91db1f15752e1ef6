import sys, numpy as np
from sm2ith_drake.run.bench import BenchmarkScenario, _Simulate
robot = sys.argv[1]; H = int(sys.argv[2]); text = sys.argv[3] if len(sys.argv) > 3 else ""
sc = BenchmarkScenario(robot, H, "orca_kkt", "rti", None, text)
log, setup, inst = _Simulate(sc, 200)
recs = [r for r in log.records if r.mode != "none"][:200]
w = np.array([r.wall_time for r in recs]) * 1e3
p = np.array([r.passes for r in recs]); it = np.array([r.iterations for r in recs])
print(robot, "median %.1f p95 %.1f p99 %.1f max %.1f" % (np.median(w), *np.percentile(w, [95, 99]), w.max()))
for npass in (1, 2):
    m = p == npass
    if m.any(): print(" passes", npass, "n", m.sum(), "median ms %.1f" % np.median(w[m]), "p90 %.1f" % np.percentile(w[m], 90), "iters med", np.median(it[m]))
o = np.argsort(w)[::-1][:12]
for i in o: print("  step", i, "%.1f ms" % w[i], "passes", p[i], "iters", it[i], recs[i].status)
print("corr iters-wall", np.corrcoef(it, w)[0,1])
