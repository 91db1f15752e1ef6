"""KKT faithfulness with 10 people predicted interactively: the bench's
10-person scenario (`sm2ith bench --humans 10`) run closed loop with
``check_predictions``, the share of SM²ITH's predicted actions within 1e-2
and 1e-3 m/s of the re-solved relaxed-ORCA QPs, with the bench's two SQP
passes and with one.

    python faithfulness_10p.py [STEPS]

STEPS: control steps per run (default 100, as 20 s at 0.2 s).
"""

import sys

import numpy as np

from sm2ith_drake.run.bench import BenchmarkScenario
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import ApplyScenarioText


def Errors(robot, passes, steps):
    scenario = BenchmarkScenario(robot, 10, "orca_kkt", rti_iterations=passes)
    scenario = ApplyScenarioText(scenario, "{controller: {check_predictions: true}}")
    log = RunSimulation(scenario, duration=steps * scenario.controller.time_step).log
    e = [
        r.prediction_errors.ravel()
        for r in log.records
        if r.mode == "solved" and r.prediction_errors is not None
    ]
    return np.concatenate(e) if e else np.zeros(0)


def main(steps):
    for passes in (2, 1):
        for robot in ("ridgeback_ur10", "stretch3"):
            e = Errors(robot, passes, steps)
            print(
                f"{robot:15s} passes {passes}: n={e.size} within1e-2 "
                f"{np.mean(e <= 1e-2) * 100:.2f}% within1e-3 "
                f"{np.mean(e <= 1e-3) * 100:.2f}% p99 {np.quantile(e, 0.99):.2e}",
                flush=True,
            )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100)
