"""Diagram builders: MakeSimulation (and RunSimulation on top of it)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Role,
    SceneGraph,
)
from pydrake.systems.analysis import (
    ApplySimulatorConfig,
    Simulator,
    SimulatorStatus,
)
from pydrake.systems.framework import DiagramBuilder, EventStatus
from pydrake.systems.primitives import MatrixGain
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.control.tasks import BasePose, BasePosition, EePosition, MakeTask
from sm2ith_drake.scenario import ControlPeriod, Scenario
from sm2ith_drake.scenario_checks import ValidateScenario
from sm2ith_drake.scenario_loader import MakeRobot
from sm2ith_drake.systems.controller import HierarchicalMpc
from sm2ith_drake.systems.humans import CrowdSimulator, HumanEstimator, MocapSensor
from sm2ith_drake.systems.logger import RunLogger
from sm2ith_drake.systems.planner import TaskPlanner
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
    stack = AddControlStack(
        builder,
        scenario,
        robot,
        tasks,
        with_estimator=scenario.perception.estimator != "truth",
        with_truth_log=has_humans,
    )
    planner, controller, logger = stack.planner, stack.controller, stack.logger
    crowd = None
    if has_humans:
        crowd = _AddCrowd(builder, scenario, robot, segments)
        builder.Connect(
            sim_robot.GetOutputPort("state"), crowd.GetInputPort("robot_state")
        )
        if stack.detections_input is not None:
            sensor = _AddMocap(builder, scenario)
            builder.Connect(
                crowd.GetOutputPort("human_truth"), sensor.GetInputPort("human_truth")
            )
            builder.Connect(sensor.GetOutputPort("detections"), stack.detections_input)
        else:
            builder.Connect(crowd.GetOutputPort("human_truth"), stack.estimate_input)
        builder.Connect(
            crowd.GetOutputPort("human_truth"), logger.GetInputPort("human_truth")
        )
    for port in stack.robot_state_inputs:
        builder.Connect(sim_robot.GetOutputPort("state"), port)
    builder.Connect(stack.command, sim_robot.GetInputPort("command"))

    # Geometry: a plant used only for its geometry, posed from q.
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = robot.AddToSceneGraph(scene_graph)
    select_q = np.hstack([robot.plant_from_q, np.zeros((n, m))])
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
                ),
            )
            builder.Connect(controller.GetOutputPort("plan"), hv.GetInputPort("plan"))
            if crowd is not None:
                builder.Connect(
                    crowd.GetOutputPort("human_truth"), hv.GetInputPort("human_truth")
                )
    diagram = builder.Build()
    diagram.set_name(f"sm2ith_{robot.name}")
    return diagram


@dataclasses.dataclass
class ControlStack:
    """What AddControlStack added, and the ports the robot side must connect.

    Attributes:
        planner, controller, logger: the TaskPlanner, HierarchicalMpc and
            RunLogger (named ``planner``, ``controller``, ``logger``).
        estimator: the HumanEstimator (``human_estimator``) or None.
        robot_state_inputs: every input port that takes the robot state
            [q; ν] (planner, controller, logger).
        detections_input: the HumanEstimator's ``detections`` input
            (HumanDetections), or None.
        estimate_input: the controller's ``human_estimate`` input when there
            is no estimator in the stack (ground-truth perception), else None.
        command: the controller's ``command`` output [u; ν_cmd].
    """

    planner: object
    controller: object
    logger: object
    estimator: object
    robot_state_inputs: list
    detections_input: object
    estimate_input: object
    command: object


def AddControlStack(
    builder,
    scenario: Scenario,
    robot,
    tasks,
    *,
    with_estimator: bool = True,
    with_truth_log: bool = False,
    with_people: bool | None = None,
    max_log_samples: int = 0,
) -> ControlStack:
    """Adds the controller side of SM²ITH to ``builder``: the TaskPlanner,
    the HierarchicalMpc, the RunLogger and (with people) the HumanEstimator,
    wired to each other.

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
        with_people: add the human prediction and estimator; defaults to
            whether the scenario lists people (on hardware, people come from
            motion capture whatever the scenario lists).
        max_log_samples: bound on the RunLogger's samples (0: unbounded).
    """
    n, m = robot.num_positions, robot.num_velocities
    period = ControlPeriod(scenario.controller)
    has_humans = bool(scenario.humans) if with_people is None else with_people
    planner = builder.AddNamedSystem(
        "planner",
        TaskPlanner(tasks, num_states=n + m, robot=robot, sequence=scenario.sequence),
    )
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
    estimator = detections = estimate = None
    if has_humans:
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
                controller.GetInputPort("human_estimate"),
            )
            detections = estimator.GetInputPort("detections")
        else:
            estimate = controller.GetInputPort("human_estimate")
    return ControlStack(
        planner=planner,
        controller=controller,
        logger=logger,
        estimator=estimator,
        robot_state_inputs=[
            planner.GetInputPort("robot_state"),
            controller.GetInputPort("robot_state"),
            logger.GetInputPort("robot_state"),
        ],
        detections_input=detections,
        estimate_input=estimate,
        command=controller.GetOutputPort("command"),
    )


def _AddCrowd(builder, scenario, robot, segments):
    return builder.AddNamedSystem(
        "crowd",
        CrowdSimulator(
            robot,
            scenario.humans,
            obstacle_segments=segments,
            time_step=scenario.crowd_time_step,
            tau=scenario.prediction.tau,
            tau_obs=scenario.prediction.tau_obs,
            model=scenario.prediction,
        ),
    )


def _AddMocap(builder, scenario):
    pc = scenario.perception
    return builder.AddNamedSystem(
        "mocap",
        MocapSensor(
            period=pc.period,
            noise=pc.noise,
            dropout_probability=pc.dropout_probability,
            seed=scenario.random_seed,
        ),
    )


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


@dataclasses.dataclass
class RunResult:
    log: object
    metrics: dict
    diagram: object
    html_path: str | None = None


def RunSimulation(
    scenario: Scenario,
    *,
    meshcat: Meshcat | None = None,
    duration: float | None = None,
    html_path: str | None = None,
    robot=None,
    tasks=None,
    progress: bool = False,
    realtime_rate: float | None = None,
    stop_when_done: bool = False,
) -> RunResult:
    """Builds and simulates ``scenario``; returns the log and its metrics.

    If ``html_path`` is given (and ``meshcat``), the run is recorded and saved
    as a self-contained HTML replay. ``realtime_rate`` overrides the
    scenario's simulator_config (1.0: real time; 0: as fast as possible).
    With ``stop_when_done`` a run with a task sequence ends as soon as its
    last phase is completed (the campaigns' navigation time); otherwise it
    runs for the scenario's duration.
    """
    from sm2ith_drake.experiments.metrics import SummarizeRun

    diagram = MakeSimulation(
        scenario=scenario, meshcat=meshcat, robot=robot, tasks=tasks
    )
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    if realtime_rate is not None:
        simulator.set_target_realtime_rate(realtime_rate)
    if meshcat is not None and html_path:
        meshcat.StartRecording(set_visualizations_while_recording=True)
    end = scenario.simulation_duration if duration is None else duration
    if stop_when_done and scenario.sequence:
        planner = diagram.GetSubsystemByName("planner")
        num_phases = len(scenario.sequence)

        def monitor(root_context):
            seq = planner.GetSequenceState(planner.GetMyContextFromRoot(root_context))
            if len(seq.completed_at) >= num_phases:
                return EventStatus.ReachedTermination(planner, "sequence completed")
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
    simulator.Initialize()
    if progress:
        steps = max(1, int(np.ceil(end)))
        for i in range(1, steps + 1):
            status = simulator.AdvanceTo(min(end, end * i / steps))
            print(
                f"\r  simulated {simulator.get_context().get_time():6.1f} / "
                f"{end:.1f} s",
                end="",
                file=sys.stderr,
                flush=True,
            )
            if (
                status.reason()
                == SimulatorStatus.ReturnReason.kReachedTerminationCondition
            ):
                break
        print(file=sys.stderr)
    else:
        simulator.AdvanceTo(end)
    context = simulator.get_context()
    logger = diagram.GetSubsystemByName("logger")
    log = logger.GetLog(logger.GetMyContextFromRoot(context))
    controller = diagram.GetSubsystemByName("controller")
    saved = None
    if meshcat is not None and html_path:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        Path(html_path).parent.mkdir(parents=True, exist_ok=True)
        Path(html_path).write_text(meshcat.StaticHtml())
        saved = str(html_path)
    metrics = SummarizeRun(
        log,
        controller.controller.robot,
        human_radii=[h.radius for h in scenario.humans] if scenario.humans else None,
    )
    if scenario.sequence:
        planner = diagram.GetSubsystemByName("planner")
        seq = planner.GetSequenceState(planner.GetMyContextFromRoot(context))
        metrics["phases_completed"] = len(seq.completed_at)
        if len(seq.completed_at) == len(scenario.sequence):
            metrics["sequence_time"] = float(seq.completed_at[-1])
    return RunResult(log=log, metrics=metrics, diagram=diagram, html_path=saved)
