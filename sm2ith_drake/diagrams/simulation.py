"""Diagram builders: MakeSimulation (and RunSimulation on top of it)."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import (
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Role,
    SceneGraph,
)
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import MatrixGain
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.control.tasks import BasePose, BasePosition, EePosition, MakeTask
from sm2ith_drake.diagrams.control_stack import AddControlStack
from sm2ith_drake.diagrams.people import AddCrowd, AddMocap
from sm2ith_drake.scenario import ControlPeriod, Scenario
from sm2ith_drake.scenario_checks import ValidateScenario
from sm2ith_drake.scenario_loader import MakeRobot
from sm2ith_drake.systems.robot import KinematicRobot
from sm2ith_drake.systems.visualization import HumanVisualizer, PlanVisualizer


def MakeSimulation(
    *, scenario: Scenario, meshcat: Meshcat | None = None, robot=None, tasks=None
):
    """Builds the closed-loop simulation Diagram of ``scenario``.

    Args:
        scenario: the configuration.
        meshcat: if given, the robot, targets and plans are drawn there.
        robot: an already-built MobileManipulator (defaults to the scenario's).
        tasks: Task objects overriding ``scenario.tasks`` (custom tasks).

    Returns:
        The Diagram, named after the robot, with subsystems ``robot``,
        ``planner``, ``controller``, ``logger`` (and ``scene_graph`` and the
        visualizers).
    """
    if tasks is None:
        ValidateScenario(scenario)
    robot = robot or MakeRobot(scenario)
    if tasks is None:
        tasks = [MakeTask(t, robot.num_positions) for t in scenario.tasks]
    n, m = robot.num_positions, robot.num_velocities
    q0 = np.asarray(scenario.robot.initial_q or robot.default_q, dtype=float)
    if q0.size != n:
        raise ValueError(f"robot.initial_q needs {n} entries, got {q0.size}")
    nu0 = np.asarray(scenario.robot.initial_nu or np.zeros(m), dtype=float)
    if nu0.size != m:
        raise ValueError(f"robot.initial_nu needs {m} entries, got {nu0.size}")
    period = ControlPeriod(scenario.controller)

    builder = DiagramBuilder()
    sim_robot = builder.AddNamedSystem(
        "robot",
        KinematicRobot(
            robot, initial_q=q0, initial_nu=nu0, time_step=scenario.robot_time_step
        ),
    )
    has_humans = bool(scenario.humans)
    segments = ObstacleSegments(scenario.obstacles)
    truth_perception = scenario.perception.estimator == "truth"
    stack = AddControlStack(
        builder,
        scenario,
        robot,
        tasks,
        with_estimator=not truth_perception,
        with_truth_log=has_humans,
        # Ideal perception sees the intents of people who walk as the model
        # says (crowd behaviour relaxed_orca), as before the estimate had them.
        with_intents=truth_perception and has_humans,
    )
    planner, controller, logger = stack.planner, stack.controller, stack.logger
    crowd = None
    if has_humans:
        crowd = AddCrowd(builder, scenario, robot, segments)
        builder.Connect(
            sim_robot.GetOutputPort("state"), crowd.GetInputPort("robot_state")
        )
        if scenario.sequence:
            # People who cross when the robot enters a phase (start_phase).
            builder.Connect(
                planner.GetOutputPort("task_references"),
                crowd.GetInputPort("task_references"),
            )
        if stack.detections_input is not None:
            sensor = AddMocap(builder, scenario)
            builder.Connect(
                crowd.GetOutputPort("human_truth"), sensor.GetInputPort("human_truth")
            )
            builder.Connect(sensor.GetOutputPort("detections"), stack.detections_input)
        else:
            builder.Connect(crowd.GetOutputPort("human_truth"), stack.estimate_input)
        if stack.intents_input is not None:
            builder.Connect(crowd.GetOutputPort("human_intents"), stack.intents_input)
        builder.Connect(
            crowd.GetOutputPort("human_truth"), logger.GetInputPort("human_truth")
        )
    for port in stack.robot_state_inputs:
        builder.Connect(sim_robot.GetOutputPort("state"), port)
    builder.Connect(stack.command, sim_robot.GetInputPort("command"))

    # Geometry: a plant used only for its geometry, posed from q.
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = robot.AddToSceneGraph(scene_graph)
    select_q = np.hstack([robot.plant_from_q, np.zeros((len(robot.plant_from_q), m))])
    q_of_state = builder.AddNamedSystem("robot.q", MatrixGain(select_q))
    to_pose = builder.AddNamedSystem(
        "robot.geometry_pose", MultibodyPositionToGeometryPose(plant)
    )
    builder.Connect(sim_robot.GetOutputPort("state"), q_of_state.get_input_port())
    builder.Connect(q_of_state.get_output_port(), to_pose.get_input_port())
    builder.Connect(
        to_pose.get_output_port(),
        scene_graph.get_source_pose_port(plant.get_source_id()),
    )

    if meshcat is not None:
        _FrameScene(meshcat, q0, tasks)
        params = MeshcatVisualizerParams(
            role=Role.kIllustration,
            publish_period=scenario.visualization.publish_period,
        )
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
        if scenario.visualization.draw_plans:
            vis = builder.AddNamedSystem(
                "plan_visualizer",
                PlanVisualizer(
                    meshcat, tasks, horizon=scenario.controller.horizon, period=period
                ),
            )
            builder.Connect(controller.GetOutputPort("plan"), vis.GetInputPort("plan"))
            builder.Connect(
                planner.GetOutputPort("task_references"),
                vis.GetInputPort("task_references"),
            )
        if has_humans or scenario.obstacles:
            hv = builder.AddNamedSystem(
                "human_visualizer",
                HumanVisualizer(
                    meshcat,
                    scenario.humans,
                    scenario.obstacles,
                    horizon=scenario.controller.horizon,
                    max_humans=scenario.prediction.max_humans if has_humans else 0,
                    period=scenario.visualization.publish_period,
                    max_extra_humans=(
                        scenario.prediction.max_extra_humans if has_humans else 0
                    ),
                    time_step=scenario.controller.time_step,
                ),
            )
            builder.Connect(controller.GetOutputPort("plan"), hv.GetInputPort("plan"))
            if stack.predictor is not None:
                builder.Connect(
                    stack.predictor.GetOutputPort("last_prediction"),
                    hv.GetInputPort("human_prediction"),
                )
            if crowd is not None:
                builder.Connect(
                    crowd.GetOutputPort("human_truth"), hv.GetInputPort("human_truth")
                )
    diagram = builder.Build()
    diagram.set_name(f"sm2ith_{robot.name}")
    return diagram


def _FrameScene(meshcat: Meshcat, q0, tasks) -> None:
    """Points the camera at the start and the task targets, from above and
    behind the start, so a replay opens on the action."""
    points = [np.array([q0[0], q0[1]])]
    for task in tasks:
        if isinstance(task, (EePosition, BasePosition, BasePose)):
            points.append(np.asarray(task.target[:2], dtype=float))
    points = np.array(points)
    center = points.mean(axis=0)
    extent = max(2.0, float(np.max(np.linalg.norm(points - center, axis=1))))
    meshcat.SetCameraPose(
        camera_in_world=[
            center[0] - 1.2 * extent,
            center[1] - 1.6 * extent,
            1.4 * extent,
        ],
        target_in_world=[center[0], center[1], 0.5],
    )
