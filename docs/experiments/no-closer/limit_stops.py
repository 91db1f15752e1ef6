"""How many of a campaign's robot-closing contacts follow a joint stopped
dead at its limit by the simulated robot (KinematicRobot: a joint at its
limit stops): every run with ``robot_closing_contact`` re-simulated, the
times at which an arm joint hit its limit recorded, and each contact
sample in which the robot closed in counted as "after a stop" when an arm
joint hit its limit within the 0.25 s before it.

    python docs/experiments/no-closer/limit_stops.py CSV FILTER [--jobs N]
"""

import sys
from multiprocessing import Pool

import numpy as np
from final_trace import TRACE, JobsOption

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.robots.planar_base import NUM_BASE_POSITIONS
from sm2ith_drake.run.metrics import RobotClosingContacts
from sm2ith_drake.systems import robot as robot_system

WINDOW = 0.25  # s


def LimitStops(row):
    stops = []
    integrate = robot_system.KinematicRobot._Integrate

    def Integrate(self, context, discrete_state):
        integrate(self, context, discrete_state)
        q = discrete_state.get_vector().CopyToVector()[: self._n]
        arm = slice(NUM_BASE_POSITIONS, None)
        robot = self._robot
        at = (q[arm] <= robot.q_lower[arm]) | (q[arm] >= robot.q_upper[arm])
        before = context.get_discrete_state_vector().CopyToVector()[: self._n]
        was = (before[arm] <= robot.q_lower[arm]) | (before[arm] >= robot.q_upper[arm])
        if np.any(at & ~was):
            stops.append(context.get_time())

    robot_system.KinematicRobot._Integrate = Integrate
    try:
        scenario = LoadRunScenario(SpecFromRow(STUDIES[row["study"]], row))
        robot, t, x, P, _, dist, gap = TRACE.Resimulate(scenario)
    finally:
        robot_system.KinematicRobot._Integrate = integrate
    closing = RobotClosingContacts(robot, x, P, gap, dist)  # (T, H)
    samples = np.nonzero(np.any(closing > 0, axis=1))[0]
    stops = np.asarray(stops)
    after = [i for i in samples if np.any((stops <= t[i]) & (stops > t[i] - WINDOW))]
    mm = closing.sum(axis=1)
    # The chance baseline: the share of all samples within WINDOW after a stop.
    near = np.array([np.any((stops <= ti) & (stops > ti - WINDOW)) for ti in t])
    return (
        row["run_id"],
        len(samples),
        len(after),
        1e3 * float(mm[samples].sum()),
        1e3 * float(mm[after].sum()) if after else 0.0,
        len(stops),
        float(near.mean()) if len(t) else 0.0,
    )


def main(argv):
    jobs, argv = JobsOption(argv)
    path, pattern = argv
    rows = [
        r
        for r in ReadRows(path)
        if pattern in r["run_id"] and r["robot_closing_contact"] is True
    ]
    with Pool(jobs) as pool:
        results = sorted(pool.map(LimitStops, rows))
    for run_id, n, a, mm, mm_a, stops, share in results:
        print(
            f"{run_id}: {n} closing samples, {a} after a limit stop; "
            f"{mm:.1f} mm, {mm_a:.1f} after a stop; {stops} stops in the run, "
            f"{share:.0%} of its samples after one"
        )
    if results:
        n = sum(r[1] for r in results)
        a = sum(r[2] for r in results)
        mm = sum(r[3] for r in results)
        mm_a = sum(r[4] for r in results)
        runs = sum(1 for r in results if r[2])
        share = np.mean([r[6] for r in results])
        print(
            f"{len(results)} runs: {a} of {n} closing samples after a limit stop "
            f"({mm_a:.0f} of {mm:.0f} mm); {runs} runs with one; by chance "
            f"{share:.0%} of the samples of these runs are after one"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
