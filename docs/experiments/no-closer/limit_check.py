"""The traced social-force contact: the Stretch 3's joint limits in the
doorway scenario and its logged state from 15.17 to 15.24 s (the wrist
yaw, q index 5 / ν index 4, reaches its 0.2 rad limit and the simulated
robot stops it).

    python docs/experiments/no-closer/limit_check.py \
        doorway_stretch3_5h/safe/social_force/SM2ITH/seed18 \
        docs/experiments/no-closer/gap-0.05-instructed-social-force/doorway.csv
"""

import sys

import numpy as np
from final_trace import TRACE

row, sc, robot, t, x, P, V, gap = TRACE.ResimulateRun(
    sys.argv[2], "doorway", sys.argv[1], lambda a, b: None
)
n = robot.num_positions
print("q limits", robot.q_lower, robot.q_upper)
print(
    "nudot limits",
    robot.nudot_lower,
    robot.nudot_upper,
    "nu limits",
    robot.nu_lower,
    robot.nu_upper,
    "robot_time_step",
    sc.robot_time_step,
)
for i in np.nonzero((t > 15.1) & (t < 15.5))[0]:
    print(f"{t[i]:.3f} q {np.round(x[i, :n], 4)} nu {np.round(x[i, n:], 3)}")
