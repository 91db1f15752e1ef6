"""Diagram builders of the hardware path: the SM²ITH controller over LCM.

:func:`MakeHardwareInterface` is the LCM counterpart of the simulated robot
and motion capture. It exposes the same port names as the simulation
(``state`` [q; ν] like KinematicRobot, ``detections`` (HumanDetections) like
MocapSensor, and a ``command`` [u; ν_cmd] input), so the controller stack of
:func:`~sm2ith_drake.diagrams.control_stack.AddControlStack` connects to
either unchanged; :func:`MakeHardwareDiagram` does exactly that, and
:func:`~sm2ith_drake.run.hardware.RunHardware` runs it in real time.

::

  LCM ─► LcmSubscriberSystem ─► RobotStateReceiver ──────► state ─────────┐
  LCM ─► LcmSubscriberSystem ─► HumanDetectionsReceiver ─► detections ──┐ │
                                    │ status        │ status            │ │
                                    ▼               ▼                   ▼ ▼
  LCM ◄─ LcmPublisherSystem ◄─ RobotCommandEncoder ◄─ CommandGate ◄─ command
                                                                (controller)

Faults are handled on this side, not in the controller:

- the receivers (:mod:`sm2ith_drake.lcm.receivers`) validate every message
  (decodable, sizes that match the robot, finite values, utime strictly
  increasing, detection ids unique and known) and count each rejection by
  reason; nothing a sender can put on a channel raises;
- the CommandGate (:mod:`sm2ith_drake.lcm.command_gate`) replaces the
  controller's command by a stop (ν_cmd = 0, braking within the acceleration
  limits) whenever the robot state it was computed from was stale or
  missing, and scales it down when the human detections are stale (the
  estimator then only predicts and its covariance grows), stopping once they
  are so old that the tracks are dropped;
- solver failures and overruns are the MpcController's own fallbacks;
- :func:`~sm2ith_drake.run.hardware.RunHardware` sends one final stop command
  on SIGINT / SIGTERM.

"Stale" compares the age of the last accepted message, since it was
received, with the timeout, on both the simulation clock (a real-time
simulator's clock) and the wall clock, whichever is older.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import (
    LcmInterfaceSystem,
    LcmPublisherSystem,
    LcmSubscriberSystem,
)

from sm2ith_drake.control.tasks import MakeTask
from sm2ith_drake.diagrams.control_stack import AddControlStack
from sm2ith_drake.lcm.codecs import RawLcmMessage
from sm2ith_drake.lcm.command_gate import MODE_NAMES, CommandGate
from sm2ith_drake.lcm.encoders import PlanEncoder, RobotCommandEncoder
from sm2ith_drake.lcm.hardware_config import (
    PUBLISH_DELAY,
    DetectionStopTimeout,
    StateTimeout,
    ValidateHardwareConfig,
)
from sm2ith_drake.lcm.receivers import HumanDetectionsReceiver, RobotStateReceiver
from sm2ith_drake.lcm.sm2ith_lcmtypes import lcmt_sm2ith_plan, lcmt_sm2ith_robot_command
from sm2ith_drake.lcm.timing import CommandMonitor, CommandTiming
from sm2ith_drake.scenario import ControlPeriod, Scenario
from sm2ith_drake.scenario_checks import ValidateScenario
from sm2ith_drake.scenario_loader import MakeRobot


def AddLcmPublisher(builder, name, channel, lcm_type, lcm, period):
    """An LcmPublisherSystem named ``name`` publishing ``lcm_type`` on
    ``channel`` every ``period``, just after the control instant
    (PUBLISH_DELAY: the systems of that instant have updated)."""
    return builder.AddNamedSystem(
        name,
        LcmPublisherSystem.Make(
            channel,
            lcm_type,
            lcm,
            publish_period=period,
            publish_offset=PUBLISH_DELAY,
        ),
    )


def MakeHardwareInterface(*, scenario: Scenario, lcm, robot=None):
    """The robot and the motion capture, over LCM.

    Args:
        scenario: channels, timeouts (``scenario.hardware``), the control
            period and the robot.
        lcm: a DrakeLcmInterface (e.g. ``DrakeLcm(scenario.hardware.lcm)``);
            an LcmInterfaceSystem inside the diagram polls it.
        robot: the MobileManipulator (defaults to the scenario's).

    Returns:
        A Diagram named ``hardware`` with the ports of the simulated robot
        and motion capture: input ``command`` [u; ν_cmd]; outputs ``state``
        [q; ν] and (with ``hardware.with_people``) ``detections``
        (HumanDetections). Inputs ``plan`` and ``controller_state`` feed the
        telemetry (with ``hardware.publish_plan``); outputs ``state_status``,
        ``detections_status`` (ReceiverState) and ``gate_status`` (GateState)
        carry the counters (see :func:`GetHardwareStatus`).
    """

    h = scenario.hardware
    ValidateHardwareConfig(h)
    robot = robot or MakeRobot(scenario)
    n, m = robot.num_positions, robot.num_velocities
    period = ControlPeriod(scenario.controller)
    q0 = np.asarray(scenario.robot.initial_q or robot.default_q, dtype=float)
    if q0.size != n:
        raise ValueError(f"robot.initial_q needs {n} entries, got {q0.size}")

    builder = DiagramBuilder()
    lcm_system = builder.AddNamedSystem("lcm", LcmInterfaceSystem(lcm))
    state_sub = builder.AddNamedSystem(
        "robot_state.subscriber",
        LcmSubscriberSystem.Make(h.state_channel, RawLcmMessage, lcm_system),
    )
    state_rx = builder.AddNamedSystem(
        "robot_state.receiver",
        RobotStateReceiver(
            robot,
            initial_q=q0,
            period=h.poll_period,
            restart_after=StateTimeout(scenario),
        ),
    )
    builder.Connect(state_sub.get_output_port(), state_rx.GetInputPort("lcm_message"))
    builder.ExportOutput(state_rx.GetOutputPort("state"), "state")
    builder.ExportOutput(state_rx.GetOutputPort("state_status"), "state_status")
    if h.with_people:
        det_sub = builder.AddNamedSystem(
            "detections.subscriber",
            LcmSubscriberSystem.Make(h.detections_channel, RawLcmMessage, lcm_system),
        )
        det_rx = builder.AddNamedSystem(
            "detections.receiver",
            HumanDetectionsReceiver(
                period=h.poll_period,
                timeout=h.detection_timeout,
                known_ids=h.human_ids,
            ),
        )
        builder.Connect(det_sub.get_output_port(), det_rx.GetInputPort("lcm_message"))
        builder.ExportOutput(det_rx.GetOutputPort("detections"), "detections")
        builder.ExportOutput(
            det_rx.GetOutputPort("detections_status"), "detections_status"
        )
    # Added after the receivers (its update at a control instant, which reads
    # the clock, runs just before the controller's) and before the
    # controller (see MakeHardwareDiagram).
    gate = builder.AddNamedSystem(
        "command_gate",
        CommandGate(
            robot,
            period=period,
            state_timeout=StateTimeout(scenario),
            with_people=h.with_people,
            detection_timeout=h.detection_timeout,
            detection_stop_timeout=DetectionStopTimeout(scenario),
            stale_speed_scale=h.stale_detection_speed_scale,
        ),
    )
    builder.Connect(state_rx.GetOutputPort("state"), gate.GetInputPort("robot_state"))
    builder.Connect(
        state_rx.GetOutputPort("state_status"), gate.GetInputPort("state_status")
    )
    if h.with_people:
        builder.Connect(
            det_rx.GetOutputPort("detections_status"),
            gate.GetInputPort("detections_status"),
        )
    builder.ExportInput(gate.GetInputPort("command"), "command")
    builder.ExportOutput(gate.GetOutputPort("gate_status"), "gate_status")
    encoder = builder.AddNamedSystem("command.encoder", RobotCommandEncoder(m))
    builder.Connect(
        gate.GetOutputPort("gated_command"), encoder.GetInputPort("gated_command")
    )
    builder.Connect(
        gate.GetOutputPort("gate_status"), encoder.GetInputPort("gate_status")
    )
    command_pub = AddLcmPublisher(
        builder,
        "command.publisher",
        h.command_channel,
        lcmt_sm2ith_robot_command,
        lcm_system,
        period,
    )
    builder.Connect(encoder.get_output_port(), command_pub.get_input_port())
    # What was actually published, read back from the bus (timing).
    command_sub = builder.AddNamedSystem(
        "command.subscriber",
        LcmSubscriberSystem.Make(h.command_channel, RawLcmMessage, lcm_system),
    )
    monitor = builder.AddNamedSystem(
        "command.monitor",
        CommandMonitor(control_period=period, period=h.poll_period),
    )
    builder.Connect(command_sub.get_output_port(), monitor.GetInputPort("lcm_message"))
    if h.publish_plan:
        plan_encoder = builder.AddNamedSystem(
            "plan.encoder", PlanEncoder(time_step=scenario.controller.time_step)
        )
        builder.ExportInput(plan_encoder.GetInputPort("plan"), "plan")
        builder.ExportInput(
            plan_encoder.GetInputPort("controller_state"), "controller_state"
        )
        builder.Connect(
            gate.GetOutputPort("gate_status"), plan_encoder.GetInputPort("gate_status")
        )
        plan_pub = AddLcmPublisher(
            builder,
            "plan.publisher",
            h.plan_channel,
            lcmt_sm2ith_plan,
            lcm_system,
            period,
        )
        builder.Connect(plan_encoder.get_output_port(), plan_pub.get_input_port())
    diagram = builder.Build()
    diagram.set_name("hardware")
    return diagram


def MakeHardwareDiagram(*, scenario: Scenario, lcm, robot=None, tasks=None):
    """The controller of ``scenario`` connected to the robot over LCM.

    The control stack is :func:`AddControlStack`, as in the simulation; the
    robot side is :func:`MakeHardwareInterface` (added first, so that at a
    control instant the gate reads the clock before the controller solves).

    Args:
        scenario: the configuration.
        lcm: a DrakeLcmInterface.
        robot: the MobileManipulator (defaults to the scenario's).
        tasks: Task objects overriding ``scenario.tasks`` (custom tasks).

    Returns:
        The Diagram, named ``sm2ith_hardware_<robot>``, with subsystems
        ``hardware``, ``planner``, ``controller``, ``logger`` and
        ``human_estimator`` (with people).
    """

    if tasks is None:
        ValidateScenario(scenario)
    robot = robot or MakeRobot(scenario)
    if tasks is None:
        tasks = [MakeTask(t, robot.num_positions) for t in scenario.tasks]
    h = scenario.hardware
    builder = DiagramBuilder()
    hardware = builder.AddSystem(
        MakeHardwareInterface(scenario=scenario, lcm=lcm, robot=robot)
    )
    stack = AddControlStack(
        builder,
        scenario,
        robot,
        tasks,
        with_estimator=True,
        with_truth_log=False,
        with_people=h.with_people,
        # About 15 minutes at 20 Hz: a controller running for hours keeps a
        # bounded log (its figures then cover the latest window).
        max_log_samples=20000,
    )
    for port in stack.robot_state_inputs:
        builder.Connect(hardware.GetOutputPort("state"), port)
    if stack.detections_input is not None:
        builder.Connect(hardware.GetOutputPort("detections"), stack.detections_input)
    builder.Connect(stack.command, hardware.GetInputPort("command"))
    if h.publish_plan:
        builder.Connect(stack.plan, hardware.GetInputPort("plan"))
        builder.Connect(
            stack.controller_state,
            hardware.GetInputPort("controller_state"),
        )
    diagram = builder.Build()
    diagram.set_name(f"sm2ith_hardware_{robot.name}")
    return diagram


def GetHardwareStatus(diagram, root_context) -> dict:
    """The counters of the hardware interface inside ``diagram`` (a
    MakeHardwareDiagram or MakeHardwareInterface result) as a plain dict."""
    hardware = (
        diagram
        if diagram.get_name() == "hardware"
        else diagram.GetSubsystemByName("hardware")
    )
    out = {}
    for name in ("robot_state.receiver", "detections.receiver"):
        if not hardware.HasSubsystemNamed(name):
            continue
        rx = hardware.GetSubsystemByName(name)
        s = rx.GetReceiverState(rx.GetMyContextFromRoot(root_context))
        out[name.split(".")[0]] = {
            "received": s.counters.received,
            "accepted": s.counters.accepted,
            "rejected": dict(s.counters.rejected),
            "restarts": s.counters.restarts,
            "last_error": s.last_error,
        }
    gate = hardware.GetSubsystemByName("command_gate")
    g = gate.GetGateState(gate.GetMyContextFromRoot(root_context))
    out["gate"] = dict(vars(g.counters))
    out["gate"]["mode"] = MODE_NAMES[g.mode]
    out["gate"]["reason"] = g.reason
    out["timing"] = GetCommandTiming(diagram, root_context).Summary()
    return out


def GetCommandTiming(diagram, root_context) -> CommandTiming:
    """The CommandTiming of the hardware interface inside ``diagram``."""
    hardware = (
        diagram
        if diagram.get_name() == "hardware"
        else diagram.GetSubsystemByName("hardware")
    )
    monitor = hardware.GetSubsystemByName("command.monitor")
    return monitor.GetTiming(monitor.GetMyContextFromRoot(root_context))
