"""A Ridgeback–UR10 among walking people, built in Python: humans,
predictor and safety settings as dataclasses, then RunSimulation.

    python examples/people_crossing.py [--meshcat] [--predictor cvmm]
"""

import argparse

from sm2ith_drake.run.metrics import FormatMetrics
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario import (
    ControllerConfig,
    HumanConfig,
    PredictionConfig,
    RobotConfig,
    SafetyConfig,
    Scenario,
    TaskConfig,
)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--meshcat", action="store_true")
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument(
        "--predictor", default="orca_kkt", choices=["orca_kkt", "cvmm", "react"]
    )
    args = parser.parse_args()

    scenario = Scenario(
        robot=RobotConfig(model="ridgeback_ur10"),
        # Carry the gripper to a target beyond the crossing (EE ≥ base).
        tasks=[
            TaskConfig(kind="ee_position", target=[5.8, 0.0, 1.0]),
            TaskConfig(kind="base_position", target=[5.0, 0.0]),
        ],
        controller=ControllerConfig(horizon=10, time_step=0.2, rti_iterations=2),
        # Two people crossing, reacting to the robot and each other (ORCA).
        humans=[
            HumanConfig(behavior="orca", start=[2.5, 3.0], waypoints=[[2.5, -3.0]]),
            HumanConfig(
                behavior="orca", start=[3.5, -3.0], waypoints=[[3.5, 3.0]], speed=0.8
            ),
        ],
        prediction=PredictionConfig(predictor=args.predictor, max_humans=2),
        safety=SafetyConfig(gamma=0.3, human_margin=0.1),
    )
    meshcat = None
    if args.meshcat:
        from pydrake.geometry import Meshcat

        meshcat = Meshcat()
        print(f"Meshcat: {meshcat.web_url()}")
    result = RunSimulation(scenario, meshcat=meshcat, duration=args.duration)
    print(FormatMetrics(result.metrics))


if __name__ == "__main__":
    main()
