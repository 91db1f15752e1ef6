"""Where the Ridgeback-UR10's unfaithful predictions are: the share of
predicted actions within 1e-2 m/s of the re-solved relaxed-ORCA QPs in
control steps where the guard holds someone and where it holds nobody,
and in steps with one SQP pass and with two (crossing_ridgeback_ur10_3h,
the seeds given).

    python faithfulness_guarded.py 0-4 ['{safety: {guard_stopping_time: false}}']
"""

import sys

import numpy as np

from sm2ith_drake.control import mpc_controller as mc
from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import ApplyScenarioText, LoadScenario

first, last = (int(s) for s in sys.argv[1].split("-"))
extra = sys.argv[2] if len(sys.argv) > 2 else "{}"
STEP = mc.MpcController.Step
rows = []


def Step(self, *args, **kwargs):
    out = STEP(self, *args, **kwargs)
    record = out[0].record if isinstance(out, tuple) else out.record
    held = self.predictor is not None and bool(np.any(self.predictor.guarded))
    if record.mode == "solved" and record.prediction_errors is not None:
        rows.append((held, record.passes, record.prediction_errors.ravel()))
    return out


mc.MpcController.Step = Step
for seed in range(first, last + 1):
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "crossing.scenarios.yaml",
        scenario_name="crossing_ridgeback_ur10_3h",
    )
    scenario = ApplyScenarioText(
        scenario, f"{{controller: {{check_predictions: true}}, random_seed: {seed}}}"
    )
    RunSimulation(ApplyScenarioText(scenario, extra))
for label, keep in (
    ("guard holds someone", lambda r: r[0]),
    ("guard holds nobody", lambda r: not r[0]),
    ("one pass", lambda r: r[1] == 1),
    ("two passes", lambda r: r[1] >= 2),
):
    chosen = [r for r in rows if keep(r)]
    e = np.concatenate([r[2] for r in chosen]) if chosen else np.zeros(0)
    share = np.mean(e <= 1e-2) * 100 if e.size else float("nan")
    print(
        f"{label:20s} steps {len(chosen):5d} actions {e.size:6d} "
        f"within1e-2 {share:6.2f}%"
    )
