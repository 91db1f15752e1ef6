"""A doorway run re-simulated with safety.turn_monitoring on and off: every
0.25 s the base pose (x, y, yaw), |ν| of the base's first two velocities,
the turn bounds' tightest yaw-rate range at that step (- where none), each
person's position and gap to the robot (surface to surface), and the
step's status.

    python docs/experiments/turn-monitoring/react_trace.py RUN_ID CSV
    python docs/experiments/turn-monitoring/react_trace.py \
        doorway_stretch3_2h/safe/orca/React/seed1 \
        docs/experiments/final-89b0a40/doorway.csv
"""

import sys

import numpy as np

from sm2ith_drake.control import mpc_controller
from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.run.metrics import HumanDistances
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import ApplyScenarioText


def Run(row, study, on):
    """Re-simulates ``row`` with the monitoring ``on`` ("true"/"false");
    returns the log's t, x, P, the people's gaps, nq, and per control step
    (time, the bounds' text, status)."""
    scenario = LoadRunScenario(SpecFromRow(STUDIES[study], row))
    scenario = ApplyScenarioText(scenario, f"{{safety: {{turn_monitoring: {on}}}}}")
    steps = []
    step = mpc_controller.MpcController.Step

    def Step(self, state, **kw):
        new = step(self, state, **kw)
        b = self.program.TurnBounds(kw["q0"], kw["nu0"])
        text = "-"
        if b is not None:
            # The yaw rate's column: the one the bounds narrow.
            w = int(np.argmax((b[1][1:] < self.robot.nu_upper).sum(axis=0)))
            text = f"[{b[0][1:, w].max():+.2f},{b[1][1:, w].min():+.2f}]"
        rec = new.last_solution
        steps.append((kw["time_now"], text, rec.status if rec is not None else "none"))
        return new

    mpc_controller.MpcController.Step = Step
    try:
        result = RunSimulation(scenario, stop_when_done=True)
    finally:
        mpc_controller.MpcController.Step = step
    log = result.log
    robot = result.diagram.GetSubsystemByName("controller").controller.robot
    t, x = np.asarray(log.times), np.asarray(log.states)
    P = np.asarray(log.human_positions)
    radii = np.array([h.radius for h in scenario.humans])
    gap = HumanDistances(robot, x, P) - radii[None]
    return t, x, P, gap, robot.num_positions, steps


def main(run_id, csv_path):
    study = next(n for n in STUDIES if run_id.startswith(n))
    row = next(r for r in ReadRows(csv_path) if r["run_id"] == run_id)
    for on in ("true", "false"):
        t, x, P, gap, nq, steps = Run(row, study, on)
        print(f"== turn_monitoring {on}: {len(t)} samples, final t {t[-1]:.1f}")
        for i in range(0, len(t), 5):
            s = min(steps, key=lambda s, ti=t[i]: abs(s[0] - ti))
            speed = np.linalg.norm(x[i, nq : nq + 2])
            people = " ".join(
                f"({P[i, j, 0]:+.1f},{P[i, j, 1]:+.1f}) {gap[i, j]:+.2f}"
                for j in range(P.shape[1])
            )
            print(
                f"{t[i]:5.1f} ({x[i, 0]:+.2f},{x[i, 1]:+.2f},{x[i, 2]:+.2f}) "
                f"v {speed:.2f} bounds {s[1]:16s} {people}  {s[2][:50]}"
            )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
