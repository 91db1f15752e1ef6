"""The 10-person bench with one change patched in (README, The 10-person
p99, fifteenth session). Not a controller.

    python var_bench.py ROBOT VARIANT [STEPS]

VARIANT: base (the shipped controller); rounds1 (after a lazy row is put
back, PIQP solves again with every row: LAZY_ROUNDS 1); gT (a far DT-CBF
row is also kept in the QP when its value h_{k+1} − 0.7 h_k at the point
is within T m of its bound, e.g. g0.15); all (lazy_barrier_distance 0)."""

import sys

from sm2ith_drake.control import cbf
from sm2ith_drake.control import piqp_workspace as pw
from sm2ith_drake.run import bench


def KeepRowsNearTheirBound(threshold):
    original = cbf.DtCbfGroup.FarRows

    def FarRows(self, point, distance):
        mask = original(self, point, distance)
        if mask is None:
            return mask
        N, H, C = self._layout.N, self._H, self._C
        h = self._HumanDistances(point)[2][0] - self._human_offset
        near = (h[1:] - 0.7 * h[:-1]) < threshold  # (N, H, C)
        rows = mask[: N * self.rows_per_step].reshape(N, self.rows_per_step)
        rows[:, : H * C] &= ~near.reshape(N, -1)
        return mask

    cbf.DtCbfGroup.FarRows = FarRows


robot, variant = sys.argv[1], sys.argv[2]
steps = int(sys.argv[3]) if len(sys.argv) > 3 else 200
text = ""
if variant == "rounds1":
    pw.LAZY_ROUNDS = 1
elif variant.startswith("g"):
    KeepRowsNearTheirBound(float(variant[1:]))
elif variant == "all":
    text = "{controller: {lazy_barrier_distance: 0}}"
elif variant != "base":
    raise SystemExit(f"unknown variant {variant}")
r = bench.RunBenchmark(robot=robot, humans=10, steps=steps, scenario_text=text)
figures = {
    k: round(v, 1) if isinstance(v, float) else v
    for k, v in r.items()
    if "ms" in k or "iter" in k
}
print(variant, robot, figures)
