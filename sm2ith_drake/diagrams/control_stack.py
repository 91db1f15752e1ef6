"""AddControlStack: the controller side of SM²ITH, the same in simulation and
on hardware.
"""

from __future__ import annotations

import dataclasses

from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.scenario import ControlPeriod, Scenario
from sm2ith_drake.systems.hierarchical_mpc import HierarchicalMpc
from sm2ith_drake.systems.humans import HumanEstimator
from sm2ith_drake.systems.logger import RunLogger
from sm2ith_drake.systems.planner import TaskPlanner
from sm2ith_drake.systems.predictor import HumanPredictor


def AddTaskPlanner(builder, scenario: Scenario, robot, tasks) -> TaskPlanner:
    """Adds the TaskPlanner (named ``planner``) that follows ``scenario``'s
    task sequence with ``tasks`` on ``robot``'s state; its ``robot_state``
    input is left for the caller to connect. The control stack's planner,
    and the driver's (which tells its simulated people the robot's phase)."""
    return builder.AddNamedSystem(
        "planner",
        TaskPlanner(
            tasks,
            num_states=robot.num_positions + robot.num_velocities,
            robot=robot,
            sequence=scenario.sequence,
        ),
    )


@dataclasses.dataclass
class ControlStack:
    """What AddControlStack added, and the ports the robot side must connect.

    Attributes:
        planner, controller, logger: the TaskPlanner, HierarchicalMpc and
            RunLogger (named ``planner``, ``controller``, ``logger``).
        estimator: the HumanEstimator (``human_estimator``) or None.
        predictor: the HumanPredictor (``human_predictor``) or None.
        robot_state_inputs: every input port that takes the robot state
            [q; ν] (planner, predictor, controller, logger).
        detections_input: the HumanEstimator's ``detections`` input
            (HumanDetections), or None.
        estimate_input: the predictor's ``human_estimate`` input when there
            is no estimator in the stack (ground-truth perception), else None.
        intents_input: the predictor's simulation-only ``human_intents``
            input (with ``with_intents``), else None.
        command: the controller's ``command`` output [u; ν_cmd].
        plan: the controller's ``plan`` output (an MpcPlan).
        controller_state: the controller's ``controller_state`` output.
    """

    planner: object
    controller: object
    logger: object
    estimator: object
    predictor: object
    robot_state_inputs: list
    detections_input: object
    estimate_input: object
    intents_input: object
    command: object
    plan: object
    controller_state: object


def AddControlStack(
    builder,
    scenario: Scenario,
    robot,
    tasks,
    *,
    with_estimator: bool = True,
    with_truth_log: bool = False,
    with_people: bool | None = None,
    with_intents: bool = False,
    max_log_samples: int = 0,
) -> ControlStack:
    """Adds the controller side of SM²ITH to ``builder``: the TaskPlanner,
    the HierarchicalMpc, the RunLogger and (with people) the HumanEstimator
    and the HumanPredictor, wired to each other:
    HumanEstimator → HumanPredictor → HierarchicalMpc.

    The simulation (MakeSimulation) and the hardware interface
    (MakeHardwareInterface) both build their controller this way and connect
    the returned ports to a simulated or a real robot, so the controller is
    the same in both.

    Args:
        builder: the DiagramBuilder.
        scenario: the configuration (controller, prediction, safety, ...).
        robot: the MobileManipulator.
        tasks: the Task objects.
        with_estimator: with people, add a HumanEstimator fed by detections
            (otherwise the controller's ``human_estimate`` input is exposed).
        with_truth_log: give the logger a ``human_truth`` input (simulation).
        with_intents: give the predictor the simulation-only
            ``human_intents`` input (the intents of people who walk as the
            model says; ground-truth perception in simulation only).
        with_people: add the human prediction and estimator; defaults to
            whether the scenario lists people (on hardware, people come from
            motion capture whatever the scenario lists).
        max_log_samples: bound on the RunLogger's samples (0: unbounded).
    """
    period = ControlPeriod(scenario.controller)
    has_humans = bool(scenario.humans) if with_people is None else with_people
    planner = AddTaskPlanner(builder, scenario, robot, tasks)
    controller = builder.AddNamedSystem(
        "controller",
        HierarchicalMpc(
            robot,
            tasks,
            scenario.controller,
            prediction=scenario.prediction if has_humans else None,
            safety=scenario.safety,
            obstacles=scenario.obstacles,
        ),
    )
    logger = builder.AddNamedSystem(
        "logger",
        # With humans, sample faster than the control rate so brief close
        # approaches are not missed by the safety metrics.
        RunLogger(
            robot,
            tasks,
            period=min(period, 0.05) if has_humans else period,
            with_humans=with_truth_log,
            max_samples=max_log_samples,
        ),
    )
    builder.Connect(
        planner.GetOutputPort("task_references"),
        controller.GetInputPort("task_references"),
    )
    builder.Connect(
        planner.GetOutputPort("task_references"), logger.GetInputPort("task_references")
    )
    builder.Connect(
        controller.GetOutputPort("controller_state"),
        logger.GetInputPort("controller_state"),
    )
    estimator = predictor = detections = estimate = intents = None
    if has_humans:
        predictor = builder.AddNamedSystem(
            "human_predictor",
            HumanPredictor(
                robot,
                scenario.prediction,
                horizon=scenario.controller.horizon,
                time_step=scenario.controller.time_step,
                control_period=period,
                obstacle_segments=ObstacleSegments(scenario.obstacles),
                human_radius=scenario.safety.human_radius,
                with_intents=with_intents,
                guard_deviation=scenario.safety.guard_deviation,
                guard_hold=scenario.safety.guard_hold,
                guard_gap=scenario.safety.guard_gap,
                guard_approach=scenario.safety.guard_approach,
            ),
        )
        builder.Connect(
            predictor.GetOutputPort("human_prediction"),
            controller.GetInputPort("human_prediction"),
        )
        builder.Connect(
            controller.GetOutputPort("plan"), predictor.GetInputPort("plan")
        )
        if with_intents:
            intents = predictor.GetInputPort("human_intents")
        if with_estimator:
            pc = scenario.perception
            estimator = builder.AddNamedSystem(
                "human_estimator",
                HumanEstimator(
                    period=pc.period,
                    measurement_noise=pc.noise,
                    acceleration_noise=pc.acceleration_noise,
                    track_timeout=pc.track_timeout,
                ),
            )
            builder.Connect(
                estimator.GetOutputPort("human_estimate"),
                predictor.GetInputPort("human_estimate"),
            )
            detections = estimator.GetInputPort("detections")
        else:
            estimate = predictor.GetInputPort("human_estimate")
    robot_state_inputs = [
        planner.GetInputPort("robot_state"),
        controller.GetInputPort("robot_state"),
        logger.GetInputPort("robot_state"),
    ]
    if predictor is not None:
        robot_state_inputs.append(predictor.GetInputPort("robot_state"))
    return ControlStack(
        planner=planner,
        controller=controller,
        logger=logger,
        estimator=estimator,
        predictor=predictor,
        robot_state_inputs=robot_state_inputs,
        detections_input=detections,
        estimate_input=estimate,
        intents_input=intents,
        command=controller.GetOutputPort("command"),
        plan=controller.GetOutputPort("plan"),
        controller_state=controller.GetOutputPort("controller_state"),
    )
