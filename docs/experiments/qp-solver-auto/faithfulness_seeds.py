"""KKT faithfulness over the crossing and corridor scenarios (README, Status)
for several perception-noise seeds: the share of SM²ITH's predicted actions
within 1e-2 and 1e-3 m/s of the re-solved relaxed-ORCA QPs, per seed and
pooled. One seed is one chaotic realization of each closed loop; the
spread over seeds says how much of a difference between two controllers is
the realization.

    python faithfulness_seeds.py SEEDS [YAML]
    python faithfulness_seeds.py 0-4 '{controller: {qp_solver: piqp}}'
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
pooled = []
for seed in range(first, last + 1):
    errors = []
    for name in NAMES:
        scenario = LoadScenario(
            filename=GetDiagramsDir() / "crossing.scenarios.yaml", scenario_name=name
        )
        scenario = ApplyScenarioText(
            scenario,
            f"{{controller: {{check_predictions: true}}, random_seed: {seed}}}",
        )
        scenario = ApplyScenarioText(scenario, extra)
        log = RunSimulation(scenario).log
        e = [
            r.prediction_errors.ravel()
            for r in log.records
            if r.mode == "solved" and r.prediction_errors is not None
        ]
        errors.append(np.concatenate(e) if e else np.zeros(0))
    e = np.concatenate(errors)
    pooled.append(e)
    print(
        f"seed {seed}: n={e.size} within1e-2 {np.mean(e <= 1e-2) * 100:.2f}% "
        f"within1e-3 {np.mean(e <= 1e-3) * 100:.2f}% p99 {np.quantile(e, 0.99):.2e}",
        flush=True,
    )
e = np.concatenate(pooled)
print(
    f"ALL seeds {first}-{last}: n={e.size} within1e-2 {np.mean(e <= 1e-2) * 100:.2f}% "
    f"within1e-3 {np.mean(e <= 1e-3) * 100:.2f}% p99 {np.quantile(e, 0.99):.2e} "
    f"worst {e.max():.3f}"
)
