"""One doorway run re-simulated and printed control step by control step
over a time window: the base's pose and speed, the planned base's
progress over the horizon, each person's position, gap (robot surface to
person surface) and speed, and whom the `safe` variant's guard holds.
For reading a freeze: what the robot faces while it stands.

    python docs/experiments/doorway-30-2026-11-28/freeze_trace.py RUN_ID [T0 T1]

RUN_ID: a row of this directory's doorway.csv, e.g.
doorway_stretch3_2h/safe/instructed/SM2ITH/seed6.
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
        prediction = kwargs.get("prediction")
        solution = new.last_solution
        if t0 <= kwargs["time_now"] <= t1 and solution is not None:
            guarded = []
            if prediction is not None and prediction.guarded.size:
                ids = np.asarray(prediction.slot_ids)
                guarded = ids[np.asarray(prediction.guarded, dtype=bool)].tolist()
            base = solution.q[:, :2]
            moves = np.linalg.norm(base[-1] - base[0])
            steps.append((kwargs["time_now"], new.record.mode, moves, guarded))

    trace = runpy.run_path(str(TRACE))
    row, _, robot, t, x, P, V, gap = trace["ResimulateRun"](
        HERE / "doorway.csv", "doorway", run_id, Record
    )
    nq = robot.num_positions
    print(
        f"{run_id}: success {row['success']}, freezing {row['freezing_time']:.1f} s, "
        f"min gap {gap.min():+.3f} m"
    )
    print("  t     mode    base (x, y, θ)       |ν_xy| plan moves  guarded  people")
    for time_now, mode, moves, guarded in steps:
        head, people = trace["StepText"](t, x, P, V, gap, nq, time_now, mode)
        print(f"{head}  {moves:.2f} m  {str(guarded):8s} {people}")


if __name__ == "__main__":
    window = (float(sys.argv[2]), float(sys.argv[3])) if len(sys.argv) > 3 else (0, 1e9)
    main(sys.argv[1], *window)
