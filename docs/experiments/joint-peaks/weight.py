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
sys.path.insert(0, str(HERE))
from seed18 import Measure  # noqa: E402

CSV = HERE / "peaks-nc05-rb" / "doorway.csv"
RUNS = (
    "doorway_ridgeback_ur10_3h/safe/orca/SM2ITH/seed2",
    "doorway_ridgeback_ur10_5h/safe/instructed/SM2ITH/seed8",
)

for run_id in RUNS:
    for weight in (1e5, 1e4, 1e3):

        def Configure(scenario, weight=weight):
            scenario.safety.no_closer_slack_weight = weight

        gap, closing = Measure(CSV, run_id, Configure)
        print(
            f"{run_id} weight {weight:.0e}: least gap {gap:.1f} mm, "
            f"robot closing in {closing:.1f} mm",
            flush=True,
        )
