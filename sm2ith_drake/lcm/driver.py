"""``sm2ith driver``: a stand-in for the robot and the motion capture on LCM.

It plays the other side of :func:`sm2ith_drake.lcm.interface.MakeHardwareInterface`
so that the whole hardware path can be exercised without a robot:

- the robot: a velocity-controlled mobile manipulator. Commands
  (``lcmt_sm2ith_robot_command``) are validated like every other message; the
  CommandFollower ramps ν toward the commanded velocity at the commanded
  acceleration and the simulation's own KinematicRobot integrates that within
  the robot's limits. Without a valid command for
  ``hardware.driver_command_timeout`` the robot brakes to a stop (its own
  watchdog). The state is published every ``hardware.driver_state_period``.
- the motion capture: simulated people (the scenario's CrowdSimulator
  behaviours: scripted, ORCA, social force, adversarial; they see the
  simulated robot) measured by the MocapSensor (noise, dropouts) and
  published every ``perception.period``.
"""

from __future__ import annotations

import math
import time

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus, LeafSystem
from pydrake.systems.lcm import (
    LcmInterfaceSystem,
    LcmPublisherSystem,
    LcmSubscriberSystem,
)

from sm2ith_drake.control.cbf import ObstacleSegments
from sm2ith_drake.control.mpc_controller import BrakingAcceleration
from sm2ith_drake.humans.messages import HumanDetections
from sm2ith_drake.lcm.interface import (
    PUBLISH_DELAY,
    CommandMonitor,
    DecodeRobotCommand,
    LcmMessageReceiver,
    RawLcmMessage,
    ReceiverState,
    StopRequest,
    WallUtime,
)
from sm2ith_drake.lcm.sm2ith_lcmtypes import (
    lcmt_sm2ith_human_detections,
    lcmt_sm2ith_robot_state,
)
from sm2ith_drake.scenario import (
    HardwareConfig,
    HumanConfig,
    PerceptionConfig,
)
from sm2ith_drake.systems.humans import CrowdSimulator, MocapSensor
from sm2ith_drake.systems.robot import KinematicRobot


class RobotCommandReceiver(LcmMessageReceiver):
    """Decodes and validates the controller's commands (the driver's side).

    .. pydrake_system::

        name: RobotCommandReceiver
        input_ports:
        - lcm_message
        output_ports:
        - command_status

    ``command_status`` is a ReceiverState whose ``value`` is the last valid
    ``lcmt_sm2ith_robot_command``.
    """

    def __init__(
        self, *, num_velocities: int, period: float, restart_after: float = math.inf
    ):
        super().__init__(period, restart_after)
        self._m = num_velocities
        self.DeclareAbstractOutputPort(
            "command_status",
            lambda: AbstractValue.Make(ReceiverState()),
            lambda context, output: output.set_value(self.GetReceiverState(context)),
        )

    def _Validate(self, context, data, last_utime, counters):
        msg = DecodeRobotCommand(data, num_velocities=self._m, last_utime=last_utime)
        return msg.utime, msg


def FollowCommand(robot, nu, velocity, acceleration, *, time_step: float):
    """The acceleration u a velocity-controlled robot applies for one
    ``time_step``: ν moves toward ``velocity`` at the rate |acceleration|
    (the robot's acceleration limit where the command gives none) and stops
    there, so a command that is held longer than the controller's period
    does not overshoot."""
    nu = np.asarray(nu, dtype=float)
    rate = np.abs(np.asarray(acceleration, dtype=float))
    rate = np.where(rate > 1e-9, rate, robot.nudot_upper)
    return np.clip((np.asarray(velocity, dtype=float) - nu) / time_step, -rate, rate)


class CommandFollower(LeafSystem):
    """Turns the last valid command into KinematicRobot's input.

    .. pydrake_system::

        name: CommandFollower
        input_ports:
        - command_status
        - robot_state
        output_ports:
        - command

    ``command`` is [u; ν_cmd] with u from :func:`FollowCommand`; with no
    command yet or none for ``command_timeout`` seconds (simulation or wall
    clock), ν_cmd = 0 and u brakes as hard as the limits allow.
    """

    def __init__(self, robot, *, time_step: float, command_timeout: float):
        super().__init__()
        self._robot = robot
        self._h = float(time_step)
        self._timeout = float(command_timeout)
        n, m = robot.num_positions, robot.num_velocities
        self._n, self._m = n, m
        self._status = self.DeclareAbstractInputPort(
            "command_status", AbstractValue.Make(ReceiverState())
        )
        self._x = self.DeclareVectorInputPort("robot_state", n + m)
        self.DeclareVectorOutputPort("command", 2 * m, self._Calc)

    def _Calc(self, context, output):
        nu = np.array(self._x.Eval(context))[self._n :]
        status = self._status.Eval(context)
        msg = status.value
        if msg is None or status.Age(context.get_time(), time.time()) > self._timeout:
            u = BrakingAcceleration(self._robot, nu, self._h)
            output.SetFromVector(np.concatenate([u, np.zeros(self._m)]))
            return
        u = FollowCommand(
            self._robot, nu, msg.velocity, msg.acceleration, time_step=self._h
        )
        output.SetFromVector(np.concatenate([u, msg.velocity]))


class RobotStateEncoder(LeafSystem):
    """Packs [q; ν] into an ``lcmt_sm2ith_robot_state`` (utime: the wall
    clock when it is published).

    .. pydrake_system::

        name: RobotStateEncoder
        input_ports:
        - state
        output_ports:
        - lcm_message
    """

    def __init__(self, num_positions: int, num_velocities: int):
        super().__init__()
        self._n, self._m = num_positions, num_velocities
        self._x = self.DeclareVectorInputPort("state", num_positions + num_velocities)
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_robot_state()),
            self._Calc,
        )

    def _Calc(self, context, output):
        x = np.array(self._x.Eval(context))
        msg = lcmt_sm2ith_robot_state()
        msg.utime = WallUtime()
        msg.num_positions = self._n
        msg.q = x[: self._n].tolist()
        msg.num_velocities = self._m
        msg.v = x[self._n :].tolist()
        output.set_value(msg)


def MakeDetectionsMessage(
    frame: HumanDetections, *, utime: int | None = None
) -> lcmt_sm2ith_human_detections:
    msg = lcmt_sm2ith_human_detections()
    msg.utime = WallUtime() if utime is None else int(utime)
    msg.num_detections = len(frame.ids)
    msg.ids = [int(i) for i in frame.ids]
    msg.positions = np.asarray(frame.positions, dtype=float).reshape(-1, 2).tolist()
    return msg


class HumanDetectionsEncoder(LeafSystem):
    """Packs a HumanDetections frame into an ``lcmt_sm2ith_human_detections``
    (utime: the wall clock when it is published).

    .. pydrake_system::

        name: HumanDetectionsEncoder
        input_ports:
        - detections
        output_ports:
        - lcm_message
    """

    def __init__(self):
        super().__init__()
        self._frame = self.DeclareAbstractInputPort(
            "detections", AbstractValue.Make(HumanDetections())
        )
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_human_detections()),
            lambda context, output: output.set_value(
                MakeDetectionsMessage(self._frame.Eval(context))
            ),
        )


def ScriptedWalkers(count: int) -> list[HumanConfig]:
    """``count`` people pacing back and forth across y ∈ [−3, 3] at
    x = 3 … 5 m, ignoring the robot (``sm2ith driver --humans N``)."""
    walkers = []
    for j in range(count):
        x = 3.0 + 2.0 * j / max(count - 1, 1)
        side = 3.0 if j % 2 == 0 else -3.0
        walkers.append(
            HumanConfig(
                behavior="scripted",
                start=[x, side],
                waypoints=[[x, -side], [x, side]],
                loop=True,
                speed=0.7 + 0.1 * (j % 3),
            )
        )
    return walkers


def MakeDriverDiagram(
    *,
    robot,
    lcm,
    hardware: HardwareConfig,
    initial_q,
    humans=(),
    perception: PerceptionConfig | None = None,
    obstacles=(),
    control_period: float = 0.2,
    time_step: float = 0.01,
    crowd_time_step: float = 0.05,
    tau: float = 2.0,
    tau_obs: float = 0.5,
    seed: int = 0,
):
    """The driver: the robot and the motion capture on the other side of LCM.

    Args:
        robot: the MobileManipulator to play.
        lcm: a DrakeLcmInterface.
        hardware: channels, state period and command watchdog.
        initial_q: where the robot starts.
        humans: HumanConfigs of the simulated people (none: no motion
            capture messages).
        perception: the motion capture's period, noise and dropouts.
        obstacles: ObstacleConfigs the people avoid.
        control_period: the controller's period (for the command timing).
        time_step: the robot's integration step (s).

    Returns:
        A Diagram named ``sm2ith_driver_<robot>`` with subsystems ``robot``
        (KinematicRobot), ``command.receiver``, ``command.follower``,
        ``command.monitor`` and (with people) ``crowd`` and ``mocap``.
    """

    perception = perception or PerceptionConfig()
    n, m = robot.num_positions, robot.num_velocities
    q0 = np.asarray(initial_q, dtype=float)
    if q0.size != n:
        raise ValueError(f"initial_q needs {n} entries, got {q0.size}")
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
        CommandMonitor(control_period=control_period, period=hardware.poll_period),
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
    state_pub = builder.AddNamedSystem(
        "state.publisher",
        LcmPublisherSystem.Make(
            hardware.state_channel,
            lcmt_sm2ith_robot_state,
            lcm_system,
            publish_period=hardware.driver_state_period,
            publish_offset=PUBLISH_DELAY,
        ),
    )
    builder.Connect(state_encoder.get_output_port(), state_pub.get_input_port())

    if humans:
        crowd = builder.AddNamedSystem(
            "crowd",
            CrowdSimulator(
                robot,
                list(humans),
                obstacle_segments=ObstacleSegments(obstacles),
                time_step=crowd_time_step,
                tau=tau,
                tau_obs=tau_obs,
            ),
        )
        builder.Connect(
            sim_robot.GetOutputPort("state"), crowd.GetInputPort("robot_state")
        )
        mocap = builder.AddNamedSystem(
            "mocap",
            MocapSensor(
                period=perception.period,
                noise=perception.noise,
                dropout_probability=perception.dropout_probability,
                seed=seed,
            ),
        )
        builder.Connect(
            crowd.GetOutputPort("human_truth"), mocap.GetInputPort("human_truth")
        )
        det_encoder = builder.AddNamedSystem(
            "detections.encoder", HumanDetectionsEncoder()
        )
        builder.Connect(
            mocap.GetOutputPort("detections"), det_encoder.GetInputPort("detections")
        )
        det_pub = builder.AddNamedSystem(
            "detections.publisher",
            LcmPublisherSystem.Make(
                hardware.detections_channel,
                lcmt_sm2ith_human_detections,
                lcm_system,
                publish_period=perception.period,
                publish_offset=PUBLISH_DELAY,
            ),
        )
        builder.Connect(det_encoder.get_output_port(), det_pub.get_input_port())
    diagram = builder.Build()
    diagram.set_name(f"sm2ith_driver_{robot.name}")
    return diagram


def RunDriver(
    *,
    robot,
    hardware: HardwareConfig,
    initial_q=None,
    humans=(),
    perception: PerceptionConfig | None = None,
    obstacles=(),
    control_period: float = 0.2,
    lcm=None,
    duration: float | None = None,
    realtime_rate: float = 1.0,
    seed: int = 0,
    log=None,
    report_period: float = 5.0,
) -> dict:
    """Runs the driver in real time until ``duration`` (None: forever) or
    SIGINT / SIGTERM. Returns a summary: the final state, the command
    counters and the timing of the commands received."""
    lcm = lcm if lcm is not None else DrakeLcm(hardware.lcm)
    q0 = robot.default_q if initial_q is None or not len(initial_q) else initial_q
    diagram = MakeDriverDiagram(
        robot=robot,
        lcm=lcm,
        hardware=hardware,
        initial_q=q0,
        humans=humans,
        perception=perception,
        obstacles=obstacles,
        control_period=control_period,
        seed=seed,
    )
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    root = simulator.get_context()
    end = math.inf if duration is None else float(duration)
    with StopRequest() as stop:

        def monitor(context):
            if stop.requested:
                return EventStatus.ReachedTermination(diagram, "stop requested")
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
        simulator.Initialize()
        next_report = report_period
        while not stop.requested and root.get_time() < end:
            simulator.AdvanceTo(min(end, root.get_time() + 0.5))
            if log is not None and root.get_time() >= next_report:
                next_report += report_period
                print(_DriverStatusLine(diagram, root), file=log, flush=True)
    summary = DriverSummary(diagram, root)
    summary["ended_by"] = "signal" if stop.requested else "duration"
    if log is not None:
        print(_DriverStatusLine(diagram, root), file=log, flush=True)
    return summary


def DriverSummary(diagram, root) -> dict:
    """The driver's state [q; ν], command counters and command timing."""
    robot = diagram.GetSubsystemByName("robot")
    x = np.array(robot.GetOutputPort("state").Eval(robot.GetMyContextFromRoot(root)))
    receiver = diagram.GetSubsystemByName("command.receiver")
    status = receiver.GetReceiverState(receiver.GetMyContextFromRoot(root))
    monitor = diagram.GetSubsystemByName("command.monitor")
    timing = monitor.GetTiming(monitor.GetMyContextFromRoot(root))
    return {
        "time": float(root.get_time()),
        "state": x.tolist(),
        "commands": {
            "received": status.counters.received,
            "accepted": status.counters.accepted,
            "rejected": dict(status.counters.rejected),
            "restarts": status.counters.restarts,
            "last_error": status.last_error,
        },
        "timing": timing.Summary(),
    }


def _DriverStatusLine(diagram, root) -> str:
    s = DriverSummary(diagram, root)
    c, t = s["commands"], s["timing"]
    lat = t["end_to_end_ms"]
    return (
        f"sm2ith driver: t={s['time']:.1f}s, commands {c['accepted']}/"
        f"{c['received']} rejected {c['rejected'] or 0}, modes {t['modes']}, "
        f"state→command "
        + ("n/a" if not lat else f"{lat['median']:.1f} ms")
        + f", x,y = {s['state'][0]:.2f}, {s['state'][1]:.2f}"
    )
