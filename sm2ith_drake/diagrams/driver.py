"""The driver's diagram (``sm2ith driver``): a stand-in for the robot and the
motion capture on the other side of LCM.

It plays the other side of :func:`~sm2ith_drake.diagrams.hardware.
MakeHardwareInterface` so that the whole hardware path can be exercised
without a robot:

- the robot: a velocity-controlled mobile manipulator. Commands
  (``lcmt_sm2ith_robot_command``) are validated like every other message; the
  CommandFollower ramps ν toward the commanded velocity at the commanded
  acceleration and the simulation's own KinematicRobot integrates that within
  the robot's limits. Without a valid command for
  ``hardware.driver_command_timeout`` the robot brakes to a stop (its own
  watchdog). The state is published every ``hardware.driver_state_period``.
- the motion capture: the scenario's simulated people, added by the same
  helpers as in the simulation (:func:`AddCrowd`, :func:`AddMocap`: scripted,
  ORCA, relaxed ORCA, social force, adversarial; they see the simulated
  robot), measured with noise and dropouts and published every
  ``perception.period``. With a task sequence, the driver runs its own
  TaskPlanner on the simulated robot's state, so people who start when the
  robot enters a phase (``start_phase``, ``waypoint_phases``) do so as in the
  simulation.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import (
    LcmInterfaceSystem,
    LcmSubscriberSystem,
)

from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.control.tasks import MakeTask
from sm2ith_drake.diagrams.control_stack import AddTaskPlanner
from sm2ith_drake.diagrams.hardware import AddLcmPublisher
from sm2ith_drake.diagrams.people import AddCrowd, AddMocap
from sm2ith_drake.lcm.codecs import RawLcmMessage
from sm2ith_drake.lcm.command_follower import CommandFollower
from sm2ith_drake.lcm.encoders import HumanDetectionsEncoder, RobotStateEncoder
from sm2ith_drake.lcm.hardware_config import ValidateHardwareConfig
from sm2ith_drake.lcm.receivers import RobotCommandReceiver
from sm2ith_drake.lcm.sm2ith_lcmtypes import (
    lcmt_sm2ith_human_detections,
    lcmt_sm2ith_robot_state,
)
from sm2ith_drake.lcm.timing import CommandMonitor
from sm2ith_drake.scenario import ControlPeriod, Scenario
from sm2ith_drake.scenario_loader import MakeRobot
from sm2ith_drake.systems.robot import KinematicRobot


def MakeDriverDiagram(*, scenario: Scenario, lcm, robot=None):
    """The driver: the robot and the motion capture on the other side of LCM.

    Args:
        scenario: what the driver plays: the robot and where it starts
            (``robot.initial_q``, else the robot's nominal pose), the people
            (``humans``, walking with ``crowd_time_step``; ``prediction`` is
            the model "relaxed_orca" people follow and the ORCA horizons),
            the ``obstacles`` they avoid, the motion capture
            (``perception``, noise seed ``random_seed``), the channels, state
            period and command watchdog (``hardware``) and the controller's
            period (for the command timing). No people: no motion-capture
            messages.
        lcm: a DrakeLcmInterface.
        robot: the MobileManipulator (defaults to the scenario's).

    Returns:
        A Diagram named ``sm2ith_driver_<robot>`` with subsystems ``robot``
        (KinematicRobot), ``command.receiver``, ``command.follower``,
        ``command.monitor``, (with people) ``crowd`` and ``mocap``, and
        (with people and a task sequence) ``planner``, the TaskPlanner that
        tells the crowd which phase the robot is in.
    """

    hardware = scenario.hardware
    ValidateHardwareConfig(hardware)
    robot = robot or MakeRobot(scenario)
    n, m = robot.num_positions, robot.num_velocities
    q0 = np.asarray(scenario.robot.initial_q or robot.default_q, dtype=float)
    if q0.size != n:
        raise ValueError(f"initial_q needs {n} entries, got {q0.size}")
    time_step = scenario.robot_time_step
    builder = DiagramBuilder()
    lcm_system = builder.AddNamedSystem("lcm", LcmInterfaceSystem(lcm))
    sim_robot = builder.AddNamedSystem(
        "robot", KinematicRobot(robot, initial_q=q0, time_step=time_step)
    )
    command_sub = builder.AddNamedSystem(
        "command.subscriber",
        LcmSubscriberSystem.Make(hardware.command_channel, RawLcmMessage, lcm_system),
    )
    receiver = builder.AddNamedSystem(
        "command.receiver",
        RobotCommandReceiver(
            num_velocities=m,
            period=hardware.poll_period,
            restart_after=hardware.driver_command_timeout,
        ),
    )
    follower = builder.AddNamedSystem(
        "command.follower",
        CommandFollower(
            robot,
            time_step=time_step,
            command_timeout=hardware.driver_command_timeout,
        ),
    )
    monitor = builder.AddNamedSystem(
        "command.monitor",
        CommandMonitor(
            control_period=ControlPeriod(scenario.controller),
            period=hardware.poll_period,
        ),
    )
    builder.Connect(command_sub.get_output_port(), receiver.GetInputPort("lcm_message"))
    builder.Connect(command_sub.get_output_port(), monitor.GetInputPort("lcm_message"))
    builder.Connect(
        receiver.GetOutputPort("command_status"),
        follower.GetInputPort("command_status"),
    )
    builder.Connect(
        sim_robot.GetOutputPort("state"), follower.GetInputPort("robot_state")
    )
    builder.Connect(
        follower.GetOutputPort("command"), sim_robot.GetInputPort("command")
    )

    state_encoder = builder.AddNamedSystem("state.encoder", RobotStateEncoder(n, m))
    builder.Connect(
        sim_robot.GetOutputPort("state"), state_encoder.GetInputPort("state")
    )
    state_pub = AddLcmPublisher(
        builder,
        "state.publisher",
        hardware.state_channel,
        lcmt_sm2ith_robot_state,
        lcm_system,
        hardware.driver_state_period,
    )
    builder.Connect(state_encoder.get_output_port(), state_pub.get_input_port())

    if scenario.humans:
        segments = ObstacleSegments(scenario.obstacles)
        crowd = AddCrowd(builder, scenario, robot, segments)
        builder.Connect(
            sim_robot.GetOutputPort("state"), crowd.GetInputPort("robot_state")
        )
        if scenario.sequence:
            # The controller's planner is on the other side of LCM; this one
            # follows the same sequence on the robot's true state.
            tasks = [MakeTask(t, n) for t in scenario.tasks]
            planner = AddTaskPlanner(builder, scenario, robot, tasks)
            builder.Connect(
                sim_robot.GetOutputPort("state"), planner.GetInputPort("robot_state")
            )
            builder.Connect(
                planner.GetOutputPort("task_references"),
                crowd.GetInputPort("task_references"),
            )
        mocap = AddMocap(builder, scenario)
        builder.Connect(
            crowd.GetOutputPort("human_truth"), mocap.GetInputPort("human_truth")
        )
        det_encoder = builder.AddNamedSystem(
            "detections.encoder", HumanDetectionsEncoder()
        )
        builder.Connect(
            mocap.GetOutputPort("detections"), det_encoder.GetInputPort("detections")
        )
        det_pub = AddLcmPublisher(
            builder,
            "detections.publisher",
            hardware.detections_channel,
            lcmt_sm2ith_human_detections,
            lcm_system,
            scenario.perception.period,
        )
        builder.Connect(det_encoder.get_output_port(), det_pub.get_input_port())
    diagram = builder.Build()
    diagram.set_name(f"sm2ith_driver_{robot.name}")
    return diagram
