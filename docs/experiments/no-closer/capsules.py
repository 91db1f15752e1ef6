"""One run re-simulated: each robot capsule's gap to one person (surface to
surface, m) and the robot's own part of its change since the previous
sample, from T0 to T1 s. The traced social-force contact:

    python docs/experiments/no-closer/capsules.py \
        doorway_stretch3_5h/safe/social_force/SM2ITH/seed18 \
        docs/experiments/no-closer/gap-0.05-instructed-social-force/doorway.csv \
        4 14.1 15.6
"""

import sys

import numpy as np
from final_trace import TRACE

from sm2ith_drake.geometry import point_segment_distance_2d


def main(run_id, csv_path, person, t0, t1):
    _, scenario, robot, t, x, P, _, _ = TRACE.ResimulateRun(
        csv_path, "doorway", run_id, lambda new, kwargs: None
    )
    j = int(person)
    radius = scenario.humans[j].radius
    nq = robot.num_positions
    ends = robot.CalcKinematics(x[:, :nq]).capsule_points[..., :2]
    d, _, _ = point_segment_distance_2d(ends[:, :, 0], ends[:, :, 1], P[:, j, None])
    gap = d - robot.capsule_radii[None] - radius
    print(f"{len(robot.capsule_radii)} capsules; q, gaps per capsule, robot's part")
    for i in np.nonzero((t > float(t0)) & (t < float(t1)))[0]:
        before, _, _ = point_segment_distance_2d(
            ends[i, :, 0], ends[i, :, 1], P[i - 1, j]
        )
        part = before - robot.capsule_radii - radius - gap[i - 1]
        print(
            f"{t[i]:.2f} q {np.round(x[i, :nq], 3)} gaps {np.round(gap[i], 3)} "
            f"robot's part {np.round(part, 4)}"
        )


if __name__ == "__main__":
    main(*sys.argv[1:])
