"""The traced social-force contact with safety.no_closer_gap, control step
by control step (14.6–15.6 s): each step's status, the measured and planned
wrist yaw rate (ν index 4 of the Stretch 3), and for each person slot the
controller counts as near, the planned gap to where the person stands
(with the controller's human radius) and the near rows' slacks.

    python docs/experiments/no-closer/near_trace.py \
        doorway_stretch3_5h/safe/social_force/SM2ITH/seed18 \
        docs/experiments/no-closer/gap-0.05-instructed-social-force/doorway.csv
"""

import sys

import numpy as np
from final_trace import TRACE

from sm2ith_drake.control import mpc_controller
from sm2ith_drake.geometry import point_segment_distance_2d

WRIST_YAW = 4  # the Stretch 3's ν: v, ω, lift, arm, wrist yaw, wrist pitch


def main(run_id, csv_path, t0=14.6, t1=15.6):
    steps, controllers = [], []
    step = mpc_controller.MpcController.Step

    def Step(self, state, **kwargs):
        controllers.append(self)
        return step(self, state, **kwargs)

    def Record(new, kwargs):
        if t0 <= kwargs["time_now"] <= t1:
            steps.append((kwargs["time_now"], new.last_solution, kwargs["nu0"]))

    mpc_controller.MpcController.Step = Step
    try:
        _, scenario, robot, *_ = TRACE.ResimulateRun(
            csv_path, "doorway", run_id, Record
        )
    finally:
        mpc_controller.MpcController.Step = step
    cbf = controllers[-1].program.cbf
    H = len(cbf.static_p0)
    radius = scenario.safety.human_radius
    for time_now, solution, nu0 in steps:
        slack = solution.z[cbf.slack[cbf.near_rows]].reshape(-1, H)
        ends = robot.CalcKinematics(solution.q).capsule_points[..., :2]
        # Where the people stood at this step (the rows' p0; the last
        # step's, as the group keeps them): close enough for a trace.
        d, _, _ = point_segment_distance_2d(
            ends[:, None, :, 0], ends[:, None, :, 1], cbf.static_p0[None, :, None]
        )
        gap = (d - robot.capsule_radii - radius).min(axis=2)  # (N+1, H)
        print(
            f"{time_now:.2f} {solution.status[:24]:24s} wrist yaw rate measured "
            f"{nu0[WRIST_YAW]:+.3f}, planned {np.round(solution.nu[:4, WRIST_YAW], 3)}"
        )
        for j in np.nonzero(gap[0] < cbf.near_gap)[0]:
            print(
                f"    slot {j}: planned gap {np.round(gap[:5, j], 4)} "
                f"near slack {np.round(slack[:, j], 4)}"
            )


if __name__ == "__main__":
    main(*sys.argv[1:3])
