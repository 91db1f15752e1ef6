"""How exactly each solver solves the stage QPs of one doorway run (React,
Stretch 3, one instructed person, seed 0, qp_solver hpipm): every stage QP
is also solved by PIQP to 1e-9 (the reference) and by PIQP at the
controller's own settings; printed: the objective gap of HPIPM and the
largest distance of each solution's inputs, and of the first wrist-yaw
input u[0, 4], from the reference.

    python docs/experiments/qp-solver-auto/first_input_gap.py
"""

import dataclasses
import sys
from pathlib import Path

import numpy as np

from sm2ith_drake.control.groups import INPUT
from sm2ith_drake.control.hpipm_workspace import HpipmWorkspace
from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.people import MergeYaml
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.run.simulation import RunSimulation

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parents[2] / "tests"))
import test_hpipm  # noqa: E402  (its PIQP reference and objective)

RUN = "doorway_stretch3_1h/safe/instructed/React/seed0"
row = next(r for r in ReadRows(HERE / "doorway" / "doorway.csv") if r["run_id"] == RUN)
spec = SpecFromRow(STUDIES["doorway"], row)
text = MergeYaml(spec.scenario_text, "{controller: {qp_solver: hpipm}}")
scenario = LoadRunScenario(dataclasses.replace(spec, scenario_text=text))
# The first wrist-yaw input (u[0, 4]) in this program's layout.
WRIST_YAW_U0 = 147
gaps = []
solve = HpipmWorkspace.Solve


def Comparing(self, p_values, q, *args):
    z, status, iterations = solve(self, p_values, q, *args)
    tight, values = test_hpipm._Piqp(self)
    reference, _, _ = tight.Solve(values(p_values), q, *args)
    own, own_values = test_hpipm._Piqp(self, tolerance=None)
    z_piqp, _, _ = own.Solve(own_values(p_values), q, *args)
    f = test_hpipm._Objective(self, p_values, q, z)
    f_ref = test_hpipm._Objective(self, p_values, q, reference)
    inputs = self.kind == INPUT
    gaps.append(
        (
            (f - f_ref) / (1 + abs(f_ref)),
            np.abs(z - reference)[inputs].max(),
            np.abs(z_piqp - reference)[inputs].max(),
            abs(z - reference)[WRIST_YAW_U0],
            abs(z_piqp - reference)[WRIST_YAW_U0],
        )
    )
    return z, status, iterations


HpipmWorkspace.Solve = Comparing
RunSimulation(scenario, duration=None, stop_when_done=True)
g = np.array(gaps)
print(f"{len(g)} stage QPs; HPIPM's objective gap (relative): max {g[:, 0].max():.1e}")
for name, column in (("HPIPM", 1), ("PIQP, own settings", 2)):
    print(
        f"{name:20s} inputs from the reference: median {np.median(g[:, column]):.1e}"
        f" p90 {np.percentile(g[:, column], 90):.1e} max {g[:, column].max():.1e};"
        f" u[0, 4]: median {np.median(g[:, column + 2]):.1e}"
        f" max {g[:, column + 2].max():.1e}"
    )
