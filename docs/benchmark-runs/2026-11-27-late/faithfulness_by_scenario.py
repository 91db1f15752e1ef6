"""KKT faithfulness per scenario (the crossing and corridor scenarios of
docs/experiments/qp-solver-auto/faithfulness_seeds.py, pooled over the
seeds given): which scenarios hold the 1e-2 m/s figure down.

    python faithfulness_by_scenario.py 0-4 ['{safety: {guard_stopping_time: false}}']
"""

import sys

import numpy as np

from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import ApplyScenarioText, LoadScenario

NAMES = [
    "crossing_ridgeback_ur10_1h",
    "crossing_ridgeback_ur10_2h",
    "crossing_ridgeback_ur10_3h",
    "crossing_stretch3_1h",
    "crossing_stretch3_2h",
    "crossing_stretch3_3h",
    "corridor_ridgeback_ur10",
    "corridor_stretch3",
]
first, last = (int(s) for s in sys.argv[1].split("-"))
extra = sys.argv[2] if len(sys.argv) > 2 else "{}"
for name in NAMES:
    errors = []
    for seed in range(first, last + 1):
        scenario = LoadScenario(
            filename=GetDiagramsDir() / "crossing.scenarios.yaml", scenario_name=name
        )
        scenario = ApplyScenarioText(
            scenario,
            f"{{controller: {{check_predictions: true}}, random_seed: {seed}}}",
        )
        scenario = ApplyScenarioText(scenario, extra)
        log = RunSimulation(scenario).log
        errors += [
            r.prediction_errors.ravel()
            for r in log.records
            if r.mode == "solved" and r.prediction_errors is not None
        ]
    e = np.concatenate(errors) if errors else np.zeros(0)
    print(
        f"{name:28s} n={e.size:6d} within1e-2 {np.mean(e <= 1e-2) * 100:6.2f}% "
        f"p99 {np.quantile(e, 0.99):.2e}",
        flush=True,
    )
