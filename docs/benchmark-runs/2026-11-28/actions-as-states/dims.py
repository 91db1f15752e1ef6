"""The stage sizes of the HPIPM structures a 20-step bench builds: per
knot the states, inputs, general rows and soft rows, and the dense-work
estimate per IPM iteration (OcpStructure.work).

    python dims.py ROBOT PEOPLE     (e.g. ridgeback_ur10 3)

Run from outside the checkout with PYTHONPATH set to the code to measure.
"""

import gc
import sys

from sm2ith_drake.control.hpipm_workspace import HpipmWorkspace
from sm2ith_drake.run.bench import BenchmarkScenario, _Simulate


def main(robot, people):
    _Simulate(BenchmarkScenario(robot, people, "orca_kkt", "rti", None, ""), 20)
    gc.unfreeze()  # the bench freezes the heap after its setup
    for ws in (o for o in gc.get_objects() if isinstance(o, HpipmWorkspace)):
        for s in ws._structures.values():
            if not hasattr(s, "X"):
                continue  # a pattern handed to PIQP
            print(f"workspace of {ws.n} variables, work {s.work:.2e}")
            print("  states ", [len(x) for x in s.X])
            print("  inputs ", [len(u) for u in s.U])
            print("  rows   ", [len(g) for g in s.g_rows])
            print("  soft   ", [len(g) for g in s.soft])


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
