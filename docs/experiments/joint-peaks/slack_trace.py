"""One run re-simulated: at each control step from T0 to T1 s, the plan's
barrier slack (m, summed over knots) on the no-closer rows (SafetyConfig.
no_closer_gap) and on the people's other barrier rows, and the least gap
to the people (m). Run it on the controller of the campaign:

    PYTHONPATH=WORKTREE python docs/experiments/joint-peaks/slack_trace.py \
        CSV RUN_ID T0 T1 [WEIGHT]
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1] / "no-closer"))
from final_trace import TRACE  # noqa: E402

from sm2ith_drake.control import mpc_controller  # noqa: E402
from sm2ith_drake.experiments.campaign import ReadRows  # noqa: E402
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow  # noqa: E402
from sm2ith_drake.experiments.studies import STUDIES  # noqa: E402


def main(csv_path, run_id, t0, t1, weight=None):
    row = next(r for r in ReadRows(csv_path) if r["run_id"] == run_id)
    scenario = LoadRunScenario(SpecFromRow(STUDIES[row["study"]], row))
    if weight is not None:
        scenario.safety.no_closer_slack_weight = float(weight)
    lines = []
    step = mpc_controller.MpcController.Step

    def Step(self, state, **kwargs):
        new = step(self, state, **kwargs)
        t = kwargs["time_now"]
        cbf = self.program.cbf
        if new.plan is not None and cbf is not None and t0 <= t <= t1:
            slack = new.plan.z[cbf.slack]
            near = np.zeros(slack.size, dtype=bool)
            near[cbf.near_rows] = True
            near_sum = float(slack[near].sum())
            walls = np.zeros(slack.size, dtype=bool)
            walls[cbf.obstacle_rows] = True
            people = float(slack[~near & ~walls].sum())
            lines.append(
                f"{t:5.2f} {new.record.status[:60]:60s} near slack {near_sum:.4f} "
                f"people's slack {people:.4f}"
            )
        return new

    mpc_controller.MpcController.Step = Step
    try:
        TRACE.Resimulate(scenario)
    finally:
        mpc_controller.MpcController.Step = step
    print("\n".join(lines))


if __name__ == "__main__":
    args = sys.argv[1:]
    main(args[0], args[1], float(args[2]), float(args[3]), *args[4:])
