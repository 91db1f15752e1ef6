"""One run of the final re-run, re-simulated and printed around its
closest approach: the base's position, heading and speed, the gap to
each person (robot surface to person surface; < 0 is contact), each
person's speed, and whether the robot's own motion closed the gap.

    python docs/experiments/final-2026-11-28/trace.py RUN_ID [SECONDS [DIR]]

e.g. RUN_ID doorway_stretch3_2h/safe/orca/SM2ITH/seed4 (a row of this
directory's CSVs).

SECONDS: how long before and after the closest approach (default 2).
DIR: the campaign directory whose CSVs hold the run (default this one).
"""

import sys
from pathlib import Path

import numpy as np

from sm2ith_drake.control import mpc_controller
from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.run.metrics import HumanDistances, RobotClosingContacts
from sm2ith_drake.run.simulation import RunSimulation

HERE = Path(__file__).parent


def Resimulate(scenario):
    """Runs ``scenario``; returns the robot, the logged times t, states x,
    people's positions P and velocities V, and each person's distance to
    the robot's surface and gap to it (surface to surface; < 0: contact)."""
    result = RunSimulation(scenario, stop_when_done=True)
    log = result.log
    robot = result.diagram.GetSubsystemByName("controller").controller.robot
    t = np.asarray(log.times)
    x = np.asarray(log.states)
    P = np.asarray(log.human_positions)
    V = np.asarray(log.human_velocities)
    radii = np.array([h.radius for h in scenario.humans])
    dist = HumanDistances(robot, x, P)
    return robot, t, x, P, V, dist, dist - radii[None]


def PeopleText(P, V, gap, digits):
    """Each person's position, gap (``digits`` decimals) and speed at one
    instant: P, V (H, 2), gap (H,)."""
    return "  ".join(
        f"p{j} ({P[j, 0]:+.2f},{P[j, 1]:+.2f}) gap {gap[j]:+.{digits}f} "
        f"v {np.linalg.norm(V[j]):.2f}"
        for j in range(len(P))
    )


def ResimulateRun(csv_path, study, run_id, record):
    """Re-simulates the run ``run_id`` of the campaign CSV ``csv_path`` (of
    ``study``), calling ``record(new, kwargs)`` after every control step
    with the controller's new state and the step's keyword arguments.
    Returns the CSV row, the scenario, and Resimulate's robot, t, x, P, V
    and gap."""
    row = next(r for r in ReadRows(csv_path) if r["run_id"] == run_id)
    scenario = LoadRunScenario(SpecFromRow(STUDIES[study], row))
    step = mpc_controller.MpcController.Step

    def Step(self, state, **kwargs):
        new = step(self, state, **kwargs)
        record(new, kwargs)
        return new

    mpc_controller.MpcController.Step = Step
    try:
        robot, t, x, P, V, _, gap = Resimulate(scenario)
    finally:
        mpc_controller.MpcController.Step = step
    return row, scenario, robot, t, x, P, V, gap


def StepText(t, x, P, V, gap, nq, time_now, mode):
    """A control step's line in the traces of the later checks: the time,
    the step's mode, the base's pose and |ν_xy| at the logged sample
    nearest ``time_now`` (before what the check adds), and the people."""
    i = int(np.argmin(np.abs(t - time_now)))
    base = x[i, :3]
    speed = np.linalg.norm(x[i, nq : nq + 2])
    head = (
        f"{time_now:6.2f} {mode:7s} ({base[0]:+.2f},{base[1]:+.2f},{base[2]:+.2f}) "
        f"{speed:.2f}"
    )
    return head, PeopleText(P[i], V[i], gap[i], 2)


def main(run_id, window, directory=HERE):
    study = next(name for name in STUDIES if run_id.startswith(name))
    csv_path = Path(directory) / f"{study}.csv"
    row = next(r for r in ReadRows(csv_path) if r["run_id"] == run_id)
    scenario = LoadRunScenario(SpecFromRow(STUDIES[study], row))
    slacks = []
    step = mpc_controller.MpcController.Step

    def Step(self, state, **kwargs):
        new = step(self, state, **kwargs)
        cbf, solution = self.program.cbf, new.last_solution
        if cbf is not None and solution is not None:
            slacks.append((kwargs["time_now"], solution, cbf))
        return new

    mpc_controller.MpcController.Step = Step
    robot, t, x, P, V, dist, gap = Resimulate(scenario)
    closing = RobotClosingContacts(robot, x, P, gap, dist).any(axis=1)
    k = int(np.argmin(gap.min(axis=1)))
    print(f"{run_id}: success {row['success']}, min gap {gap.min():+.3f} m", end="")
    print(f" at {t[k]:.2f} s")
    nq = robot.num_positions
    for i in np.nonzero(np.abs(t - t[k]) <= window)[0][::2]:
        base = x[i, :3]
        speed = np.linalg.norm(x[i, nq : nq + 2]) if x.shape[1] > nq + 1 else np.nan
        people = PeopleText(P[i], V[i], gap[i], 3)
        print(
            f"{t[i]:6.2f} base ({base[0]:+.2f},{base[1]:+.2f},{base[2]:+.2f}) "
            f"|nu| {speed:.2f} {'CLOSING' if closing[i] else '       '} {people}"
        )

    print("control step: DT-CBF slack per person slot (knots 1-2 / horizon), guard")
    for time_now, solution, cbf in slacks:
        if abs(time_now - t[k]) > window:
            continue
        N, per_step = len(solution.q) - 1, cbf.rows_per_step
        value = solution.z[cbf.slack]
        H, C = cbf._H, cbf._C  # noqa: SLF001 (a diagnostic reads the layout)
        people = value[: N * per_step].reshape(N, per_step)[:, : H * C]
        people = people.reshape(N, H, C).max(axis=2)  # (N, H)
        guard = value[N * per_step :]
        ids = solution.human_slot_ids
        text = "  ".join(
            f"slot {j} (id {ids[j] if ids is not None else '-'}) "
            f"{people[:2, j].max():.3f} / {people[:, j].max():.3f}"
            for j in range(H)
        )
        print(f"{time_now:6.2f} {text}  guard {guard.max() if guard.size else 0:.3f}")


if __name__ == "__main__":
    main(
        sys.argv[1],
        float(sys.argv[2]) if len(sys.argv) > 2 else 2.0,
        sys.argv[3] if len(sys.argv) > 3 else HERE,
    )
