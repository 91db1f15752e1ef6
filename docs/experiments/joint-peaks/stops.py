"""How hard the simulated robot's arm joints hit their limits: every run of
a campaign CSV whose run_id contains FILTER re-simulated with the
controller's joint rows between the knots on (``on``) or off (``off``, the
controller before them), and every time an arm joint hit a limit recorded
with the speed it had just before (KinematicRobot stops a joint at its
limit dead). A joint the plan brings to its limit at rest hits it at a few
mrad/s at most (the plant integrates at 10 ms); one the plan swings past it
between the knots hits it at speed.

    python docs/experiments/joint-peaks/stops.py CSV FILTER on|off [--jobs N]

Prints per run: stops, stops faster than 0.05 rad/s (or m/s), the speed
lost in all; then the totals.
"""

import sys
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1] / "no-closer"))
from final_trace import TRACE, JobsOption  # noqa: E402

from sm2ith_drake.experiments.campaign import ReadRows  # noqa: E402
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow  # noqa: E402
from sm2ith_drake.experiments.studies import STUDIES  # noqa: E402
from sm2ith_drake.robots.planar_base import (  # noqa: E402
    NUM_BASE_POSITIONS,
    ArmVelocityIndex,
)
from sm2ith_drake.systems import robot as robot_system  # noqa: E402

FAST = 0.05  # rad/s or m/s


def Stops(job):
    row, between_knots = job
    lost = []
    integrate = robot_system.KinematicRobot._Integrate

    def Integrate(self, context, discrete_state):
        integrate(self, context, discrete_state)
        robot, n = self._robot, self._n
        arm = np.arange(NUM_BASE_POSITIONS, n)
        after = discrete_state.get_vector().CopyToVector()
        before = context.get_discrete_state_vector().CopyToVector()

        def At(q):
            return (q[arm] <= robot.q_lower[arm]) | (q[arm] >= robot.q_upper[arm])

        hit = arm[At(after[:n]) & ~At(before[:n])]
        lost.extend(np.abs(before[n + ArmVelocityIndex(robot, hit)]))

    robot_system.KinematicRobot._Integrate = Integrate
    try:
        scenario = LoadRunScenario(SpecFromRow(STUDIES[row["study"]], row))
        scenario.controller.joint_limits_between_knots = between_knots
        TRACE.Resimulate(scenario)
    finally:
        robot_system.KinematicRobot._Integrate = integrate
    lost = np.asarray(lost)
    return row["run_id"], lost.size, int(np.sum(lost > FAST)), float(lost.sum())


def main(argv):
    jobs, argv = JobsOption(argv)
    path, pattern, setting = argv
    if setting not in ("on", "off"):
        raise SystemExit("the third argument is on or off")
    rows = [r for r in ReadRows(path) if pattern in r["run_id"]]
    with Pool(jobs) as pool:
        results = sorted(pool.map(Stops, [(r, setting == "on") for r in rows]))
    for run_id, n, fast, speed in results:
        print(f"{run_id}: {n} stops, {fast} faster than {FAST}, {speed:.3f} lost")
    n = sum(r[1] for r in results)
    fast = sum(r[2] for r in results)
    speed = sum(r[3] for r in results)
    print(
        f"{len(results)} runs, rows between the knots {setting}: {n} stops, "
        f"{fast} faster than {FAST}, {speed:.2f} lost in all"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
