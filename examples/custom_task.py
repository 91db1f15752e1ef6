"""A custom task: keep the end effector at a fixed height while the base
drives, written as a Task subclass and passed to RunSimulation.

    python examples/custom_task.py [--duration 6]
"""

import argparse

import numpy as np

from sm2ith_drake.control.tasks import BasePosition, Task
from sm2ith_drake.run.metrics import FormatMetrics
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario import RobotConfig, Scenario
from sm2ith_drake.scenario_loader import MakeRobot


class EeHeight(Task):
    """e = z_WE(q) − target: one component of the EE position."""

    def __init__(self, **kwargs):
        super().__init__(dim=1, **kwargs)

    def CalcErrorAndJacobian(self, qs, kin, target):
        # kin.p_WE is (K, 3) and kin.J_WE (K, 3, n) for the K steps.
        return kin.p_WE[:, 2:3] - target, kin.J_WE[:, 2:3, :]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=6.0)
    args = parser.parse_args()

    scenario = Scenario(robot=RobotConfig(model="ridgeback_ur10"))
    robot = MakeRobot(scenario)
    tasks = [
        EeHeight(name="ee_height", target=[0.5], weight=10.0),
        BasePosition(name="base", target=[2.0, 1.0], num_positions=robot.num_positions),
    ]
    result = RunSimulation(scenario, robot=robot, tasks=tasks, duration=args.duration)
    print(FormatMetrics(result.metrics))
    z = np.asarray(result.log.p_WE)[:, 2]
    print(f"EE height over the run: min {z.min():.3f} m, max {z.max():.3f} m")


if __name__ == "__main__":
    main()
