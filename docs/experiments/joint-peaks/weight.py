"""The two deep Ridgeback–UR10 contacts of `peaks-nc05-rb` (the joint rows
and safety.no_closer_gap 0.05, controller f5a4557) re-simulated with the
option's slack weight (safety.no_closer_slack_weight) at 1e5 (the
default), 1e4 (a person's barrier slack weight) and 1e3. Run it on the
controller of the campaign (a worktree of f5a4557 on PYTHONPATH):

    PYTHONPATH=WORKTREE python docs/experiments/joint-peaks/weight.py
"""

import sys
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "no-closer"))
from final_trace import TRACE  # noqa: E402

from sm2ith_drake.experiments.campaign import ReadRows  # noqa: E402
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow  # noqa: E402
from sm2ith_drake.experiments.studies import STUDIES  # noqa: E402
from sm2ith_drake.run.metrics import RobotClosingContacts  # noqa: E402

CSV = HERE / "peaks-nc05-rb" / "doorway.csv"
RUNS = (
    "doorway_ridgeback_ur10_3h/safe/orca/SM2ITH/seed2",
    "doorway_ridgeback_ur10_5h/safe/instructed/SM2ITH/seed8",
)

for run_id in RUNS:
    row = next(r for r in ReadRows(CSV) if r["run_id"] == run_id)
    for weight in (1e5, 1e4, 1e3):
        scenario = LoadRunScenario(SpecFromRow(STUDIES[row["study"]], row))
        scenario.safety.no_closer_slack_weight = weight
        robot, t, x, P, _, dist, gap = TRACE.Resimulate(scenario)
        closing = RobotClosingContacts(robot, x, P, gap, dist)
        print(
            f"{run_id} weight {weight:.0e}: least gap "
            f"{1e3 * float(gap.min()):.1f} mm, robot closing in "
            f"{1e3 * float(closing.sum()):.1f} mm",
            flush=True,
        )
