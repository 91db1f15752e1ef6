"""KKT faithfulness with 10 people: the bench scenario simulated with
check_predictions (README, Benchmark, fourteenth session).

    python faithfulness_10.py YAML SECONDS
"""

import sys

import numpy as np

from sm2ith_drake.run.bench import BenchmarkScenario
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import ApplyScenarioText

extra = sys.argv[1]
seconds = float(sys.argv[2])
for robot in ["ridgeback_ur10", "stretch3"]:
    s = BenchmarkScenario(robot, 10, "orca_kkt", scenario_text=extra)
    s = ApplyScenarioText(
        s,
        f"{{controller: {{check_predictions: true}}, simulation_duration: {seconds}}}",
    )
    log = RunSimulation(s).log
    e = np.concatenate(
        [
            r.prediction_errors.ravel()
            for r in log.records
            if r.mode == "solved" and r.prediction_errors is not None
        ]
    )
    modes = {}
    for r in log.records:
        modes[r.mode] = modes.get(r.mode, 0) + 1
    print(
        robot,
        extra,
        f"n={e.size} within1e-2 {np.mean(e <= 1e-2) * 100:.2f}% "
        f"within1e-3 {np.mean(e <= 1e-3) * 100:.2f}% "
        f"p99 {np.quantile(e, 0.99):.2e} worst {e.max():.3f} modes {modes}",
        flush=True,
    )
