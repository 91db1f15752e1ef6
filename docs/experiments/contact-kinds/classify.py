"""What kind of contact each run with contact is: every run of a campaign
CSV with contact (``collision``), re-simulated, classified at its deepest
sample (the base's velocity from the logged states; "behind" is relative to
the direction the base is moving in):

- ``robot closing``: the robot's own motion closed the gap then
  (``robot_closing_contact``'s rule at that sample);
- ``from behind``: the base moves at ≥ 0.1 m/s and the person is behind it,
  walking the same way: a person catching up with a robot that drives away;
- ``into a still robot``: the base moves at < 0.05 m/s and the person moves
  at ≥ 0.05 m/s;
- ``both still``: neither moves faster (a jam);
- ``other``: the rest (the person beside or ahead of a moving robot).

    python docs/experiments/contact-kinds/classify.py CSV [FILTER] [--jobs N]

e.g. CSV docs/experiments/final-89b0a40/doorway.csv, FILTER "safe/orca/SM2ITH"
(a substring of the run ids).
"""

import importlib.util
import sys
from collections import Counter
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.run.metrics import RobotClosingContacts

# The final re-run's trace (its Resimulate), loaded from its file: its
# name would otherwise be the standard library's ``trace``.
_SPEC = importlib.util.spec_from_file_location(
    "final_trace", Path(__file__).parents[1] / "final-2026-11-28" / "trace.py"
)
_TRACE = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_TRACE)
Resimulate = _TRACE.Resimulate


def Classify(row):
    study = STUDIES[row["study"]]
    scenario = LoadRunScenario(SpecFromRow(study, row))
    robot, t, x, P, V, dist, gap = Resimulate(scenario)
    closing = RobotClosingContacts(robot, x, P, gap, dist).any(axis=1)
    i, j = np.unravel_index(np.argmin(gap), gap.shape)
    lo, hi = max(i - 1, 0), min(i + 1, len(t) - 1)
    v_base = (x[hi, :2] - x[lo, :2]) / max(t[hi] - t[lo], 1e-9)
    speed = float(np.linalg.norm(v_base))
    person_speed = float(np.linalg.norm(V[i, j]))
    rel = P[i, j] - x[i, :2]
    if closing[i]:
        kind = "robot closing"
    elif speed >= 0.1 and rel @ v_base < 0 and V[i, j] @ v_base > 0:
        kind = "from behind"
    elif speed < 0.05:
        kind = "into a still robot" if person_speed >= 0.05 else "both still"
    else:
        kind = "other"
    return (
        f"{row['run_id']}: {kind}; gap {gap[i, j] * 1e3:+.1f} mm at {t[i]:.2f} s, "
        f"base {speed:.2f} m/s, person {person_speed:.2f} m/s",
        kind,
    )


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--jobs")]
    jobs = int(next((a.split("=")[1] for a in sys.argv if a.startswith("--jobs=")), 2))
    csv_path, pattern = args[0], args[1] if len(args) > 1 else ""
    rows = [
        r
        for r in ReadRows(csv_path)
        if r["collision"] in (True, "True") and pattern in r["run_id"]
    ]
    with Pool(jobs) as pool:
        results = pool.map(Classify, rows)
    for line, _ in sorted(results):
        print(line)
    counts = Counter(kind for _, kind in results)
    print(
        f"{len(results)} runs with contact: "
        + ", ".join(f"{kind} {n}" for kind, n in counts.most_common())
    )


if __name__ == "__main__":
    main()
