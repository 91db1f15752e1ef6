"""One head-on run (adversarial.csv of this directory) re-simulated and
printed control step by control step: the base's pose and speed, how far
the planned base gets toward its goal over the horizon (+: closer), the
person's position, gap (robot surface to person surface) and speed, and
where the plan predicts the person at the horizon's end.

    python docs/experiments/seeds-30-2026-11-28/headon_trace.py RUN_ID [T0 T1]

RUN_ID e.g. headon_stretch3/paper/social_force/SM2ITH/seed28.
"""

import runpy
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
# The final re-run's trace.py (its ResimulateRun and StepText).
TRACE = HERE.parent / "final-2026-11-28" / "trace.py"


def main(run_id, t0, t1):
    steps = []

    def Record(new, kwargs):
        solution = new.last_solution
        if t0 <= kwargs["time_now"] <= t1 and solution is not None:
            base = solution.q[:, :2]
            target = kwargs["targets"]["base_position"]
            gain = np.linalg.norm(base[0] - target) - np.linalg.norm(base[-1] - target)
            end = None
            if solution.human_predictions is not None:
                end = solution.human_predictions[-1, 0]
            steps.append((kwargs["time_now"], new.record.mode, gain, end))

    trace = runpy.run_path(str(TRACE))
    row, scenario, robot, t, x, P, V, gap = trace["ResimulateRun"](
        HERE / "adversarial.csv", "adversarial", run_id, Record
    )
    nq = robot.num_positions
    goal = next(t.target for t in scenario.tasks if t.kind == "base_position")
    print(
        f"{run_id}: success {row['success']}, progress share "
        f"{row['progress_share']:.3f}, min gap {gap.min():+.3f} m, "
        f"goal {np.asarray(goal, dtype=float)}"
    )
    print(
        "  t     mode    base (x, y, θ)       |ν_xy| plan gain  predicted end  people"
    )
    for time_now, mode, gain, end in steps:
        head, people = trace["StepText"](t, x, P, V, gap, nq, time_now, mode)
        where = "-" if end is None else f"({end[0]:+.2f},{end[1]:+.2f})"
        print(f"{head}  {gain:+.2f} m  {where:14s} {people}")


if __name__ == "__main__":
    window = (float(sys.argv[2]), float(sys.argv[3])) if len(sys.argv) > 3 else (0, 1e9)
    main(sys.argv[1], *window)
