"""The sixteenth session's traced contact (no-closer/README.md): the
Stretch 3's doorway, 5 social-force people, SM²ITH in `safe` with
safety.no_closer_gap 0.05, seed 18 (a 34 mm contact, the robot closing in
as the wrist came back off its limit) re-simulated with the joint rows
between the knots off (the controller it was traced on) and on.

    python docs/experiments/joint-peaks/seed18.py
"""

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "no-closer"))
from final_trace import TRACE  # noqa: E402

from sm2ith_drake.experiments.campaign import ReadRows  # noqa: E402
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow  # noqa: E402
from sm2ith_drake.experiments.studies import STUDIES  # noqa: E402
from sm2ith_drake.run.metrics import RobotClosingContacts  # noqa: E402

RUN = "doorway_stretch3_5h/safe/social_force/SM2ITH/seed18"
CSV = HERE.parent / "no-closer" / "gap-0.05-instructed-social-force" / "doorway.csv"


def Measure(csv_path, run_id, configure):
    """Re-simulates ``run_id`` of ``csv_path`` after ``configure(scenario)``;
    returns its least gap to the people and the robot's closing in (mm)."""
    row = next(r for r in ReadRows(csv_path) if r["run_id"] == run_id)
    scenario = LoadRunScenario(SpecFromRow(STUDIES[row["study"]], row))
    configure(scenario)
    robot, t, x, P, _, dist, gap = TRACE.Resimulate(scenario)
    closing = RobotClosingContacts(robot, x, P, gap, dist)
    return 1e3 * float(np.min(gap)), 1e3 * float(closing.sum())


def main():
    row = next(r for r in ReadRows(CSV) if r["run_id"] == RUN)
    print(f"{RUN}, as logged: least gap {1e3 * row['min_human_gap']:.1f} mm")
    for between_knots in (False, True):

        def Configure(scenario, on=between_knots):
            scenario.controller.joint_limits_between_knots = on

        gap, closing = Measure(CSV, RUN, Configure)
        print(
            f"rows between the knots {'on' if between_knots else 'off'}: least gap "
            f"{gap:.1f} mm, robot closing in {closing:.1f} mm"
        )


if __name__ == "__main__":
    main()
