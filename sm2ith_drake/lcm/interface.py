"""The hardware path: the SM²ITH controller diagram over LCM.

:func:`MakeHardwareInterface` is the LCM counterpart of the simulated robot
and motion capture. It exposes the same port names as the simulation
(``state`` [q; ν] like KinematicRobot, ``detections`` (HumanDetections) like
MocapSensor, and a ``command`` [u; ν_cmd] input), so the controller stack of
:func:`sm2ith_drake.diagrams.AddControlStack` connects to either unchanged;
:func:`MakeHardwareDiagram` does exactly that, and :func:`RunHardware` runs it
in real time.

::

  LCM ─► LcmSubscriberSystem ─► RobotStateReceiver ──────► state ─────────┐
  LCM ─► LcmSubscriberSystem ─► HumanDetectionsReceiver ─► detections ──┐ │
                                    │ status        │ status            │ │
                                    ▼               ▼                   ▼ ▼
  LCM ◄─ LcmPublisherSystem ◄─ RobotCommandEncoder ◄─ CommandGate ◄─ command
                                                                (controller)

Faults are handled here, not in the controller:

- the receivers validate every message (decodable, sizes that match the
  robot, finite values, utime strictly increasing, detection ids unique and
  known) and count each rejection by reason; nothing a sender can put on a
  channel raises;
- the CommandGate replaces the controller's command by a stop (ν_cmd = 0,
  braking within the acceleration limits) whenever the robot state it was
  computed from was stale or missing, and scales it down when the human
  detections are stale (the estimator then only predicts and its covariance
  grows), stopping once they are so old that the tracks are dropped;
- solver failures and overruns are the MpcController's own fallbacks;
- :func:`RunHardware` sends one final stop command on SIGINT / SIGTERM.

"Stale" compares the age of the last accepted message, since it was
received, with the timeout, on both the simulation clock (a real-time
simulator's clock) and the wall clock, whichever is older.
"""

from __future__ import annotations

import copy
import itertools
import math
import signal
import threading
import time
from dataclasses import dataclass, field

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

from sm2ith_drake.control.mpc_controller import BrakingAcceleration, ControllerState
from sm2ith_drake.control.tasks import MakeTask
from sm2ith_drake.diagrams.control_stack import AddControlStack
from sm2ith_drake.humans.messages import HumanDetections, MpcPlan
from sm2ith_drake.lcm.sm2ith_lcmtypes import (
    lcmt_sm2ith_human_detections,
    lcmt_sm2ith_plan,
    lcmt_sm2ith_robot_command,
    lcmt_sm2ith_robot_state,
)
from sm2ith_drake.scenario import ControlPeriod, HardwareConfig, Scenario, ScenarioError
from sm2ith_drake.scenario_checks import ValidateScenario
from sm2ith_drake.scenario_loader import MakeRobot

MODE_CONTROL = lcmt_sm2ith_robot_command.MODE_CONTROL
MODE_SLOWED = lcmt_sm2ith_robot_command.MODE_SLOWED
MODE_STOP = lcmt_sm2ith_robot_command.MODE_STOP
MODE_NAMES = {MODE_CONTROL: "control", MODE_SLOWED: "slowed", MODE_STOP: "stop"}

# Commands are published this long after the control step, so that they carry
# the step's result (Drake handles publish events at t before the updates at
# t) and leave as soon as it is computed.
PUBLISH_DELAY = 1e-3


def WallUtime() -> int:
    """The wall clock in microseconds (the utime of published messages)."""
    return time.time_ns() // 1000


# ---------------------------------------------------------------------------
# Raw messages and validation (plain functions, testable without Drake).


class RawLcmMessage:
    """The bytes of one LCM message, undecoded.

    Used as the ``lcm_type`` of an LcmSubscriberSystem so that decoding (and
    rejecting garbage) happens in a receiver LeafSystem instead of inside
    LCM's message handler, where an exception would stop the simulator. Each
    received message gets a new ``sequence`` number (0: none yet).
    """

    _counter = itertools.count(1)

    def __init__(self, data: bytes = b"", sequence: int = 0):
        self.data = bytes(data)
        self.sequence = sequence

    def encode(self) -> bytes:
        return self.data

    @staticmethod
    def decode(data) -> RawLcmMessage:
        return RawLcmMessage(bytes(data), next(RawLcmMessage._counter))


class MessageRejected(ValueError):
    """A message that fails validation; ``reason`` is its counter key."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


# Rejection reasons (counter keys).
UNDECODABLE = "undecodable"  # not this type, truncated or garbled bytes
WRONG_SIZE = "wrong_size"  # sizes that do not match the robot
NON_FINITE = "non_finite"  # NaN or infinite values
TIME_NOT_INCREASING = "time_not_increasing"  # utime repeated or backwards
DUPLICATE_ID = "duplicate_id"  # a detection id twice in one frame
UNKNOWN_ID = "unknown_id"  # one detection dropped (counted per detection)


def _Decode(lcm_type, data: bytes):
    try:
        return lcm_type.decode(data)
    except Exception as e:  # garbage may fail in struct, unicode, ...
        raise MessageRejected(UNDECODABLE, f"{type(e).__name__}: {e}") from e


def _CheckTime(utime: int, last_utime: int) -> None:
    if utime <= last_utime:
        raise MessageRejected(TIME_NOT_INCREASING, f"utime {utime} after {last_utime}")


def DecodeRobotState(
    data: bytes, *, num_positions: int, num_velocities: int, last_utime: int = 0
):
    """Decodes and validates an ``lcmt_sm2ith_robot_state``.

    Returns:
        (utime, q, ν).

    Raises:
        MessageRejected: with the reason.
    """
    msg = _Decode(lcmt_sm2ith_robot_state, data)
    if msg.num_positions != num_positions or msg.num_velocities != num_velocities:
        raise MessageRejected(
            WRONG_SIZE,
            f"{msg.num_positions} positions, {msg.num_velocities} velocities "
            f"(expected {num_positions}, {num_velocities})",
        )
    q = np.asarray(msg.q, dtype=float)
    v = np.asarray(msg.v, dtype=float)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        raise MessageRejected(NON_FINITE)
    _CheckTime(msg.utime, last_utime)
    return msg.utime, q, v


def DecodeHumanDetections(
    data: bytes, *, last_utime: int = 0, known_ids=None
) -> tuple[int, np.ndarray, np.ndarray, int]:
    """Decodes and validates an ``lcmt_sm2ith_human_detections``.

    Detections with an id < 0 or (if ``known_ids`` is given) not in it are
    dropped from the frame.

    Returns:
        (utime, ids, positions (k, 2), number of dropped unknown ids).

    Raises:
        MessageRejected: undecodable, non-finite, repeated ids or time.
    """
    msg = _Decode(lcmt_sm2ith_human_detections, data)
    ids = np.asarray(msg.ids, dtype=int).reshape(-1)
    positions = np.asarray(msg.positions, dtype=float).reshape(-1, 2)
    if len(ids) != len(positions):
        raise MessageRejected(WRONG_SIZE, "ids and positions differ in length")
    if not np.all(np.isfinite(positions)):
        raise MessageRejected(NON_FINITE)
    if len(np.unique(ids)) != len(ids):
        raise MessageRejected(DUPLICATE_ID, f"ids {ids.tolist()}")
    _CheckTime(msg.utime, last_utime)
    known = ids >= 0
    if known_ids:
        known &= np.isin(ids, np.asarray(list(known_ids), dtype=int))
    return msg.utime, ids[known], positions[known], int(np.sum(~known))


def DecodeRobotCommand(data: bytes, *, num_velocities: int, last_utime: int = 0):
    """Decodes and validates an ``lcmt_sm2ith_robot_command`` (the driver's
    side). Returns the message.

    Raises:
        MessageRejected: with the reason.
    """
    msg = _Decode(lcmt_sm2ith_robot_command, data)
    if msg.num_velocities != num_velocities:
        raise MessageRejected(
            WRONG_SIZE,
            f"{msg.num_velocities} velocities (expected {num_velocities})",
        )
    values = np.concatenate([msg.velocity, msg.acceleration, [msg.speed_scale]])
    if not np.all(np.isfinite(values)):
        raise MessageRejected(NON_FINITE)
    _CheckTime(msg.utime, last_utime)
    return msg


# ---------------------------------------------------------------------------
# Receivers.


@dataclass
class MessageCounters:
    """What a receiver did with the messages it saw."""

    received: int = 0
    accepted: int = 0
    # Accepted although their utime went back, after the stream had been
    # silent long enough that the sender is taken to have restarted.
    restarts: int = 0
    # Rejections by reason (see the reason constants).
    rejected: dict = field(default_factory=dict)

    @property
    def num_rejected(self) -> int:
        return int(sum(self.rejected.values()))


@dataclass
class ReceiverState:
    """A receiver's state: the last accepted message and the counters.

    ``value`` is the decoded content (receiver specific); ``receive_time``
    and ``receive_wall`` are the simulation and wall-clock times (s) at which
    it was accepted (−∞: nothing accepted yet).
    """

    sequence: int = 0
    utime: int = 0
    value: object = None
    receive_time: float = -math.inf
    receive_wall: float = -math.inf
    counters: MessageCounters = field(default_factory=MessageCounters)
    last_error: str = ""

    def Age(self, time_now: float, wall_now: float | None = None) -> float:
        """Seconds since the last accepted message, on the simulation clock
        and (if ``wall_now`` is given) the wall clock, whichever is more."""
        age = time_now - self.receive_time
        if wall_now is not None:
            age = max(age, wall_now - self.receive_wall)
        return age


class LcmMessageReceiver(LeafSystem):
    """The common part of the receivers: polls an LcmSubscriberSystem's
    RawLcmMessage output every ``period`` and keeps the last message that
    passes ``_Validate`` (subclasses), counting the others by reason.

    A message whose utime is not later than the last accepted one is
    rejected, unless the stream has been silent for ``restart_after``
    seconds: then the sender is taken to have restarted (its clock may start
    over) and the message is accepted and counted in ``restarts``.
    """

    def __init__(self, period: float, restart_after: float = math.inf):
        super().__init__()
        self._restart_after = float(restart_after)
        self._raw = self.DeclareAbstractInputPort(
            "lcm_message", AbstractValue.Make(RawLcmMessage())
        )
        self._status = self.DeclareAbstractState(
            AbstractValue.Make(self._InitialState())
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Poll)

    def _InitialState(self) -> ReceiverState:
        return ReceiverState()

    def GetReceiverState(self, context) -> ReceiverState:
        return context.get_abstract_state(self._status).get_value()

    def _Poll(self, context, state):
        raw = self._raw.Eval(context)
        old = self.GetReceiverState(context)
        if raw.sequence == old.sequence:
            self._Idle(context, old, state)
            return
        new = copy.copy(old)
        new.counters = copy.deepcopy(old.counters)
        new.sequence = raw.sequence
        new.counters.received += 1
        restarted = old.Age(context.get_time(), time.time()) > self._restart_after
        last_utime = 0 if restarted else old.utime
        try:
            new.utime, new.value = self._Validate(
                context, raw.data, last_utime, new.counters
            )
        except MessageRejected as e:
            rejected = new.counters.rejected
            rejected[e.reason] = rejected.get(e.reason, 0) + 1
            new.last_error = str(e)
            state.get_mutable_abstract_state(self._status).set_value(new)
            self._Idle(context, new, state)
            return
        new.counters.accepted += 1
        if new.utime <= old.utime:
            new.counters.restarts += 1
        new.receive_time = context.get_time()
        new.receive_wall = time.time()
        state.get_mutable_abstract_state(self._status).set_value(new)

    def _Idle(self, context, receiver_state, state) -> None:
        """Called at a poll without a new valid message."""

    def _Validate(self, context, data: bytes, last_utime: int, counters):
        """Returns (utime, value) or raises MessageRejected."""
        raise NotImplementedError


class RobotStateReceiver(LcmMessageReceiver):
    """Decodes and validates the robot state from LCM.

    .. pydrake_system::

        name: RobotStateReceiver
        input_ports:
        - lcm_message
        output_ports:
        - state
        - state_status

    ``lcm_message`` is the RawLcmMessage of an ``lcmt_sm2ith_robot_state``
    subscriber. ``state`` is [q; ν] of the last accepted message (before the
    first: ``initial_q`` at rest); ``state_status`` the ReceiverState (age,
    utime, counters). A robot that was silent for ``restart_after`` seconds
    may start its utime over (a restarted driver).
    """

    def __init__(
        self, robot, *, initial_q, period: float, restart_after: float = math.inf
    ):
        super().__init__(period, restart_after)
        self._n, self._m = robot.num_positions, robot.num_velocities
        self._x0 = np.concatenate([np.asarray(initial_q, float), np.zeros(self._m)])
        self.DeclareVectorOutputPort("state", self._n + self._m, self._CalcState)
        self.DeclareAbstractOutputPort(
            "state_status",
            lambda: AbstractValue.Make(ReceiverState()),
            lambda context, output: output.set_value(self.GetReceiverState(context)),
        )

    def _Validate(self, context, data, last_utime, counters):
        utime, q, v = DecodeRobotState(
            data,
            num_positions=self._n,
            num_velocities=self._m,
            last_utime=last_utime,
        )
        return utime, np.concatenate([q, v])

    def _CalcState(self, context, output):
        value = self.GetReceiverState(context).value
        output.SetFromVector(self._x0 if value is None else value)


class HumanDetectionsReceiver(LcmMessageReceiver):
    """Decodes and validates motion-capture frames from LCM.

    .. pydrake_system::

        name: HumanDetectionsReceiver
        input_ports:
        - lcm_message
        output_ports:
        - detections
        - detections_status

    ``detections`` is the HumanDetections of the last accepted frame, stamped
    with the (simulation) time it was received, so HumanEstimator fuses it
    exactly as it fuses MocapSensor's frames. While no frame has been
    accepted for ``timeout`` seconds it is an empty frame at each poll: the
    estimator only predicts, the covariance grows, and tracks unseen for the
    estimator's track timeout are dropped, as when people are missed in
    simulation. Detections with ids outside ``known_ids`` (if given) or < 0
    are dropped and counted.
    """

    def __init__(self, *, period: float, timeout: float, known_ids=()):
        self._timeout = float(timeout)
        self._known_ids = [int(i) for i in known_ids]
        super().__init__(period, restart_after=timeout)
        self.DeclareAbstractOutputPort(
            "detections",
            lambda: AbstractValue.Make(HumanDetections()),
            self._CalcDetections,
        )
        self.DeclareAbstractOutputPort(
            "detections_status",
            lambda: AbstractValue.Make(ReceiverState()),
            lambda context, output: output.set_value(self.GetReceiverState(context)),
        )

    def _InitialState(self):
        s = ReceiverState()
        s.value = HumanDetections(time=-math.inf)
        return s

    def _Validate(self, context, data, last_utime, counters):
        utime, ids, positions, unknown = DecodeHumanDetections(
            data, last_utime=last_utime, known_ids=self._known_ids
        )
        if unknown:
            counters.rejected[UNKNOWN_ID] = (
                counters.rejected.get(UNKNOWN_ID, 0) + unknown
            )
        # Stamped when it is received, on this process's clock (the
        # sender's clock need not agree with it).
        frame = HumanDetections(time=context.get_time(), ids=ids, positions=positions)
        return utime, frame

    def _Idle(self, context, receiver_state, state):
        if receiver_state.Age(context.get_time()) <= self._timeout:
            return
        new = copy.copy(receiver_state)
        new.value = HumanDetections(time=context.get_time())
        state.get_mutable_abstract_state(self._status).set_value(new)

    def _CalcDetections(self, context, output):
        output.set_value(self.GetReceiverState(context).value)


# ---------------------------------------------------------------------------
# The command gate and the encoders.


@dataclass
class GateCounters:
    """Control steps by what was sent."""

    control: int = 0
    slowed: int = 0
    stopped: int = 0
    # Steps stopped because the robot state was stale or missing, and
    # because the people were unknown (detections too old).
    stale_state: int = 0
    people_unknown: int = 0


@dataclass
class GateState:
    """The CommandGate's decision at the last control step."""

    mode: int = MODE_STOP
    speed_scale: float = 0.0
    reason: str = "no control step yet"
    # ν of the state the step used (for braking and scaling).
    nu: np.ndarray | None = None
    # Timing telemetry (µs): the state's own utime, when it was received
    # and when the control step read it (wall clock).
    state_utime: int = 0
    state_receive_utime: int = 0
    control_utime: int = 0
    counters: GateCounters = field(default_factory=GateCounters)


def GateCommand(
    robot, command, nu, *, mode: int, speed_scale: float, period: float
) -> np.ndarray:
    """The command [u; ν_cmd] actually sent, given the controller's
    ``command`` and the gate's decision.

    - control: unchanged;
    - slowed: ν_cmd scaled by ``speed_scale`` (the base keeps its path: v and
      ω scale together), u the acceleration that reaches it in one period;
    - stop (or a non-finite command): ν_cmd = 0 and u brakes within the
      acceleration limits.
    """
    m = robot.num_velocities
    command = np.asarray(command, dtype=float)
    nu = np.nan_to_num(np.zeros(m) if nu is None else np.asarray(nu, dtype=float))
    if mode == MODE_STOP or not np.all(np.isfinite(command)):
        return np.concatenate([BrakingAcceleration(robot, nu, period), np.zeros(m)])
    if mode == MODE_SLOWED:
        nu_cmd = speed_scale * command[m:]
        u = np.clip((nu_cmd - nu) / period, robot.nudot_lower, robot.nudot_upper)
        return np.concatenate([u, nu_cmd])
    return command.copy()


class CommandGate(LeafSystem):
    """Lets the controller's command through only while its inputs are fresh.

    At every control step (the controller's period, same instants) it reads
    how old the robot state and the detections are; the command published
    after that step is then (see :func:`GateCommand`):

    - a stop if the robot state is missing or older than ``state_timeout``,
      or the detections are older than ``detection_stop_timeout`` (the people
      are no longer known);
    - slowed by ``stale_speed_scale`` if the detections are older than
      ``detection_timeout``;
    - the controller's command otherwise.

    .. pydrake_system::

        name: CommandGate
        input_ports:
        - command
        - robot_state
        - state_status
        - detections_status (with people)
        output_ports:
        - gated_command
        - gate_status
    """

    def __init__(
        self,
        robot,
        *,
        period: float,
        state_timeout: float,
        with_people: bool = False,
        detection_timeout: float = math.inf,
        detection_stop_timeout: float = math.inf,
        stale_speed_scale: float = 0.3,
    ):
        super().__init__()
        self._robot = robot
        self._period = float(period)
        self._state_timeout = float(state_timeout)
        self._detection_timeout = float(detection_timeout)
        self._detection_stop_timeout = float(detection_stop_timeout)
        self._scale = float(stale_speed_scale)
        n, m = robot.num_positions, robot.num_velocities
        self._n, self._m = n, m
        self._command = self.DeclareVectorInputPort("command", 2 * m)
        self._x = self.DeclareVectorInputPort("robot_state", n + m)
        self._state_status = self.DeclareAbstractInputPort(
            "state_status", AbstractValue.Make(ReceiverState())
        )
        self._detections_status = None
        if with_people:
            self._detections_status = self.DeclareAbstractInputPort(
                "detections_status", AbstractValue.Make(ReceiverState())
            )
        self._gate = self.DeclareAbstractState(AbstractValue.Make(GateState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(self._period, 0.0, self._Decide)
        self.DeclareVectorOutputPort("gated_command", 2 * m, self._CalcCommand)
        self.DeclareAbstractOutputPort(
            "gate_status",
            lambda: AbstractValue.Make(GateState()),
            lambda context, output: output.set_value(self.GetGateState(context)),
        )

    def GetGateState(self, context) -> GateState:
        return context.get_abstract_state(self._gate).get_value()

    def _Decide(self, context, state):
        wall = time.time()
        now = context.get_time()
        old = self.GetGateState(context)
        new = GateState(counters=copy.copy(old.counters))
        new.control_utime = int(wall * 1e6)
        robot_status = self._state_status.Eval(context)
        x = np.array(self._x.Eval(context))
        new.nu = x[self._n :]
        new.state_utime = robot_status.utime
        if np.isfinite(robot_status.receive_wall):
            new.state_receive_utime = int(robot_status.receive_wall * 1e6)
        mode, scale, reason = MODE_CONTROL, 1.0, ""
        detection_age = -math.inf
        if self._detections_status is not None:
            detection_age = self._detections_status.Eval(context).Age(now, wall)
        if robot_status.value is None:
            mode, reason = MODE_STOP, "no robot state received"
            new.counters.stale_state += 1
        elif (age := robot_status.Age(now, wall)) > self._state_timeout:
            mode, reason = MODE_STOP, f"robot state {age:.3f} s old"
            new.counters.stale_state += 1
        elif detection_age > self._detection_stop_timeout:
            mode, reason = MODE_STOP, "no human detections (people unknown)"
            new.counters.people_unknown += 1
        elif detection_age > self._detection_timeout:
            mode, scale = MODE_SLOWED, self._scale
            reason = f"human detections {detection_age:.3f} s old"
        if mode == MODE_STOP:
            scale = 0.0
            new.counters.stopped += 1
        elif mode == MODE_SLOWED:
            new.counters.slowed += 1
        else:
            new.counters.control += 1
        new.mode, new.speed_scale, new.reason = mode, scale, reason
        state.get_mutable_abstract_state(self._gate).set_value(new)

    def _CalcCommand(self, context, output):
        gate = self.GetGateState(context)
        output.SetFromVector(
            GateCommand(
                self._robot,
                self._command.Eval(context),
                gate.nu,
                mode=gate.mode,
                speed_scale=gate.speed_scale,
                period=self._period,
            )
        )


def MakeCommandMessage(
    command, gate: GateState, *, utime: int | None = None
) -> lcmt_sm2ith_robot_command:
    """The ``lcmt_sm2ith_robot_command`` of ``command`` [u; ν_cmd]."""
    command = np.asarray(command, dtype=float)
    m = len(command) // 2
    msg = lcmt_sm2ith_robot_command()
    msg.utime = WallUtime() if utime is None else int(utime)
    msg.state_utime = int(gate.state_utime)
    msg.state_receive_utime = int(gate.state_receive_utime)
    msg.control_utime = int(gate.control_utime)
    msg.mode = int(gate.mode)
    msg.speed_scale = float(gate.speed_scale)
    msg.num_velocities = m
    msg.velocity = command[m:].tolist()
    msg.acceleration = command[:m].tolist()
    return msg


class RobotCommandEncoder(LeafSystem):
    """Packs the gated command into an ``lcmt_sm2ith_robot_command`` (utime:
    the wall clock when it is published).

    .. pydrake_system::

        name: RobotCommandEncoder
        input_ports:
        - gated_command
        - gate_status
        output_ports:
        - lcm_message
    """

    def __init__(self, num_velocities: int):
        super().__init__()
        self._command = self.DeclareVectorInputPort("gated_command", 2 * num_velocities)
        self._gate = self.DeclareAbstractInputPort(
            "gate_status", AbstractValue.Make(GateState())
        )
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_robot_command()),
            lambda context, output: output.set_value(
                MakeCommandMessage(
                    self._command.Eval(context), self._gate.Eval(context)
                )
            ),
        )


def MakePlanMessage(
    plan_solution, controller_state, *, state_utime: int, time_step: float
) -> lcmt_sm2ith_plan:
    """The ``lcmt_sm2ith_plan`` of an MpcSolution (or None) and the
    ControllerState's last step record."""
    msg = lcmt_sm2ith_plan()
    msg.utime = WallUtime()
    msg.state_utime = int(state_utime)
    record = controller_state.record
    msg.mode = record.mode
    msg.status = record.status
    msg.solve_time = float(record.solve_time)
    msg.time_step = float(time_step)
    sol = plan_solution
    if sol is None:
        return msg
    q = np.asarray(sol.q, dtype=float)
    msg.num_steps = len(q)
    msg.base_pose = q[:, :3].tolist()
    msg.ee_position = np.asarray(sol.p_WE, dtype=float).reshape(-1, 3).tolist()
    if sol.human_predictions is not None and sol.human_slot_ids is not None:
        slots = np.nonzero(np.asarray(sol.human_slot_ids) >= 0)[0]
        msg.num_humans = len(slots)
        msg.human_ids = [int(sol.human_slot_ids[j]) for j in slots]
        predictions = np.asarray(sol.human_predictions, dtype=float)
        msg.human_positions = [predictions[:, j, :].tolist() for j in slots]
    return msg


class PlanEncoder(LeafSystem):
    """Packs the controller's plan into an ``lcmt_sm2ith_plan`` (telemetry).

    .. pydrake_system::

        name: PlanEncoder
        input_ports:
        - plan
        - controller_state
        - gate_status
        output_ports:
        - lcm_message
    """

    def __init__(self, *, time_step: float):
        super().__init__()

        self._time_step = float(time_step)
        self._plan = self.DeclareAbstractInputPort(
            "plan", AbstractValue.Make(MpcPlan())
        )
        self._ctrl = self.DeclareAbstractInputPort(
            "controller_state", AbstractValue.Make(ControllerState())
        )
        self._gate = self.DeclareAbstractInputPort(
            "gate_status", AbstractValue.Make(GateState())
        )
        self.DeclareAbstractOutputPort(
            "lcm_message",
            lambda: AbstractValue.Make(lcmt_sm2ith_plan()),
            self._Calc,
        )

    def _Calc(self, context, output):
        output.set_value(
            MakePlanMessage(
                self._plan.Eval(context).solution,
                self._ctrl.Eval(context),
                state_utime=self._gate.Eval(context).state_utime,
                time_step=self._time_step,
            )
        )


# ---------------------------------------------------------------------------
# The interface diagram and the hardware diagram.


def ValidateHardwareConfig(config: HardwareConfig) -> None:
    """Checks the values of ``config``; raises ScenarioError."""

    for name in ("state", "command", "detections", "plan"):
        if not getattr(config, f"{name}_channel"):
            raise ScenarioError(f"hardware.{name}_channel must not be empty")
    if config.poll_period <= 0 or config.driver_state_period <= 0:
        raise ScenarioError("hardware.poll_period and driver_state_period must be > 0")
    for name in (
        "state_timeout",
        "detection_timeout",
        "detection_stop_timeout",
        "driver_command_timeout",
    ):
        if getattr(config, name) < 0:
            raise ScenarioError(f"hardware.{name} must be ≥ 0")
    if not 0 <= config.stale_detection_speed_scale <= 1:
        raise ScenarioError("hardware.stale_detection_speed_scale must be in [0, 1]")
    if any(i < 0 for i in config.human_ids):
        raise ScenarioError("hardware.human_ids must be ≥ 0")


def StateTimeout(scenario: Scenario) -> float:
    """hardware.state_timeout, or two control periods if it is 0."""
    h = scenario.hardware
    return (
        h.state_timeout
        if h.state_timeout > 0
        else 2 * ControlPeriod(scenario.controller)
    )


def DetectionStopTimeout(scenario: Scenario) -> float:
    """hardware.detection_stop_timeout, or the estimator's track timeout."""
    h = scenario.hardware
    if h.detection_stop_timeout > 0:
        return h.detection_stop_timeout
    return scenario.perception.track_timeout


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
    command_pub = builder.AddNamedSystem(
        "command.publisher",
        LcmPublisherSystem.Make(
            h.command_channel,
            lcmt_sm2ith_robot_command,
            lcm_system,
            publish_period=period,
            publish_offset=PUBLISH_DELAY,
        ),
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
        plan_pub = builder.AddNamedSystem(
            "plan.publisher",
            LcmPublisherSystem.Make(
                h.plan_channel,
                lcmt_sm2ith_plan,
                lcm_system,
                publish_period=period,
                publish_offset=PUBLISH_DELAY,
            ),
        )
        builder.Connect(plan_encoder.get_output_port(), plan_pub.get_input_port())
    diagram = builder.Build()
    diagram.set_name("hardware")
    return diagram


def MakeHardwareDiagram(*, scenario: Scenario, lcm, robot=None, tasks=None):
    """The controller of ``scenario`` connected to the robot over LCM.

    The control stack is :func:`sm2ith_drake.diagrams.AddControlStack`, as in
    the simulation; the robot side is :func:`MakeHardwareInterface` (added
    first, so that at a control instant the gate reads the clock before the
    controller solves).

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
        builder.Connect(
            stack.controller.GetOutputPort("plan"), hardware.GetInputPort("plan")
        )
        builder.Connect(
            stack.controller.GetOutputPort("controller_state"),
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


# ---------------------------------------------------------------------------
# Timing, and running in real time.


class CommandTiming:
    """Timing of the published commands, from their own time stamps.

    Fed every ``lcmt_sm2ith_robot_command`` seen on the command channel (by
    whichever process listens: the controller itself or the driver), it
    measures, in milliseconds:

    - ``control_jitter_ms``: |Δ − period| between successive control steps
      (when each step read its state, ``control_utime``): the control
      period's jitter;
    - ``publish_jitter_ms``: the same between successive publications
      (``utime``), which also varies with the solve time;
    - ``latency_ms``: from the control step reading the state to the
      command's publication (utime − control_utime), the state-to-command
      latency of the controller;
    - ``state_age_ms``: how old the state was when the step read it
      (control_utime − state_receive_utime);
    - ``end_to_end_ms``: from the robot's state stamp to the command
      (utime − state_utime: across processes, on one host's clock).

    At most ``max_samples`` commands are kept for the figures (all are
    counted by mode).
    """

    def __init__(self, period: float, max_samples: int = 100_000):
        self.period = float(period)
        self.max_samples = max_samples
        self.modes = {name: 0 for name in MODE_NAMES.values()}
        self.rejected = 0
        self.sequence = 0  # of the last RawLcmMessage seen
        self.last = None
        self.utimes: list[int] = []
        self.control_utimes: list[int] = []
        self.latency: list[float] = []
        self.state_age: list[float] = []
        self.end_to_end: list[float] = []

    def Add(self, msg) -> None:
        self.modes[MODE_NAMES.get(msg.mode, "stop")] += 1
        self.last = msg
        if len(self.utimes) >= self.max_samples:
            return
        self.utimes.append(msg.utime)
        if msg.control_utime <= 0 or (
            self.control_utimes and msg.control_utime <= self.control_utimes[-1]
        ):
            return  # not a new control step (e.g. the final stop at exit)
        self.control_utimes.append(msg.control_utime)
        self.latency.append((msg.utime - msg.control_utime) * 1e-6)
        if msg.mode != MODE_STOP and msg.state_utime > 0:
            self.end_to_end.append((msg.utime - msg.state_utime) * 1e-6)
            if msg.state_receive_utime > 0:
                self.state_age.append(
                    (msg.control_utime - msg.state_receive_utime) * 1e-6
                )

    def AddBytes(self, data: bytes) -> None:
        """Decodes and adds (garbage is only counted)."""
        try:
            self.Add(lcmt_sm2ith_robot_command.decode(data))
        except Exception:
            self.rejected += 1

    def Summary(self) -> dict:
        """The figures (ms: median, p95, max; None without samples)."""

        def stats(values):
            if not len(values):
                return None
            a = np.asarray(values) * 1e3
            return {
                "median": float(np.median(a)),
                "p95": float(np.percentile(a, 95)),
                "max": float(np.max(a)),
            }

        publish = np.diff(np.asarray(self.utimes, dtype=float)) * 1e-6
        control = np.diff(np.asarray(self.control_utimes, dtype=float)) * 1e-6
        return {
            "commands": len(self.utimes),
            "modes": dict(self.modes),
            "rejected": self.rejected,
            "period_ms": stats(control),
            "control_jitter_ms": stats(np.abs(control - self.period)),
            "publish_jitter_ms": stats(np.abs(publish - self.period)),
            "latency_ms": stats(self.latency),
            "state_age_ms": stats(self.state_age),
            "end_to_end_ms": stats(self.end_to_end),
        }


class CommandMonitor(LeafSystem):
    """Listens to the command channel and keeps a CommandTiming of what was
    actually published.

    .. pydrake_system::

        name: CommandMonitor
        input_ports:
        - lcm_message

    The CommandTiming lives in the Context (see :meth:`GetTiming`) and, like
    RunLogger's log, grows in a periodic publish event (``period``: the
    polling period) rather than being copied at every poll.
    """

    def __init__(self, *, control_period: float, period: float):
        super().__init__()
        self._raw = self.DeclareAbstractInputPort(
            "lcm_message", AbstractValue.Make(RawLcmMessage())
        )
        self._timing = self.DeclareAbstractState(
            AbstractValue.Make(CommandTiming(control_period))
        )
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Poll)

    def GetTiming(self, context) -> CommandTiming:
        return context.get_abstract_state(self._timing).get_value()

    def _Poll(self, context):
        raw = self._raw.Eval(context)
        timing = self.GetTiming(context)
        if raw.sequence != timing.sequence:
            timing.sequence = raw.sequence
            timing.AddBytes(raw.data)


class StopRequest:
    """Turns SIGINT / SIGTERM into a request the simulator's monitor sees."""

    def __init__(self):
        self.requested = False
        self.signal = None
        self._previous = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._Handle)
        return self

    def _Handle(self, signum, frame):
        self.requested = True
        self.signal = signum

    def __exit__(self, *exc):
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        return False


def PublishStopCommand(
    lcm, scenario: Scenario, robot, nu, gate=None
) -> lcmt_sm2ith_robot_command:
    """Publishes one stop command (ν_cmd = 0, braking from ``nu``) and
    returns it."""
    period = ControlPeriod(scenario.controller)
    gate = copy.copy(gate) if gate is not None else GateState()
    gate.mode, gate.speed_scale = MODE_STOP, 0.0
    command = GateCommand(
        robot,
        np.zeros(2 * robot.num_velocities),
        nu,
        mode=MODE_STOP,
        speed_scale=0.0,
        period=period,
    )
    msg = MakeCommandMessage(command, gate)
    lcm.Publish(scenario.hardware.command_channel, msg.encode())
    return msg


def RunHardware(
    scenario: Scenario,
    *,
    lcm=None,
    duration: float | None = None,
    realtime_rate: float = 1.0,
    report_period: float = 5.0,
    log=None,
    stop_request: StopRequest | None = None,
) -> dict:
    """Runs the controller of ``scenario`` against LCM until ``duration``
    (None: forever) or SIGINT / SIGTERM, then publishes one final stop
    command.

    Args:
        scenario: the configuration (``scenario.hardware`` for LCM).
        lcm: a DrakeLcm (default: one made from ``scenario.hardware.lcm``).
        duration: seconds to run (None: until a signal).
        realtime_rate: 1.0 on hardware; tests may run faster on memq://.
        report_period: seconds between status lines on ``log``.
        log: a text stream for status lines (None: quiet).

    Returns:
        A summary dict: timing (CommandTiming.Summary), the controller's
        solve and step times (ms), its counters, the hardware counters, the
        final task errors and why the run ended.
    """

    robot = MakeRobot(scenario)
    lcm = lcm if lcm is not None else DrakeLcm(scenario.hardware.lcm)
    diagram = MakeHardwareDiagram(scenario=scenario, lcm=lcm, robot=robot)
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    root = simulator.get_context()
    hardware = diagram.GetSubsystemByName("hardware")
    timing = GetCommandTiming(diagram, root)
    end = math.inf if duration is None else float(duration)
    with stop_request or StopRequest() as stop:

        def monitor(context):
            if stop.requested:
                return EventStatus.ReachedTermination(diagram, "stop requested")
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
        reason = "error"
        try:
            simulator.Initialize()
            next_report = report_period
            while not stop.requested and root.get_time() < end:
                simulator.AdvanceTo(min(end, root.get_time() + 0.5))
                if log is not None and root.get_time() >= next_report:
                    next_report += report_period
                    print(_StatusLine(diagram, root, timing), file=log, flush=True)
            reason = "signal" if stop.requested else "duration"
        finally:
            # Whatever ended the run (even an exception), the robot is told
            # to stop.
            state_rx = hardware.GetSubsystemByName("robot_state.receiver")
            x = state_rx.GetOutputPort("state").Eval(
                state_rx.GetMyContextFromRoot(root)
            )
            gate = hardware.GetSubsystemByName("command_gate")
            final = PublishStopCommand(
                lcm,
                scenario,
                robot,
                np.asarray(x)[robot.num_positions :],
                gate.GetGateState(gate.GetMyContextFromRoot(root)),
            )
    summary = _Summary(diagram, root, timing)
    summary["ended_by"] = reason
    summary["final_command"] = {
        "mode": MODE_NAMES[final.mode],
        "velocity": list(final.velocity),
        "acceleration": list(final.acceleration),
    }
    if log is not None:
        print(_StatusLine(diagram, root, timing), file=log, flush=True)
    return summary


def _ControllerFigures(diagram, root) -> dict:
    logger = diagram.GetSubsystemByName("logger")
    log = logger.GetLog(logger.GetMyContextFromRoot(root))
    records = [r for r in log.records if r.mode != "none"]
    # The first step includes the solver's setup.
    steady = records[1:] if len(records) > 1 else records
    out = {"steps": len(records)}
    for key, attr in (("solve_ms", "solve_time"), ("step_ms", "wall_time")):
        values = np.array([getattr(r, attr) for r in steady]) * 1e3
        out[key] = (
            {
                "median": float(np.median(values)),
                "p95": float(np.percentile(values, 95)),
                "max": float(values.max()),
            }
            if len(values)
            else None
        )
    counters = log.counters
    out["counters"] = dict(vars(counters)) if counters is not None else {}
    out["task_errors"] = {
        name: float(np.linalg.norm(errors[-1]))
        for name, errors in log.task_errors.items()
        if errors
    }
    return out


def _Summary(diagram, root, timing: CommandTiming) -> dict:
    summary = {
        "time": float(root.get_time()),
        "timing": timing.Summary(),
        "controller": _ControllerFigures(diagram, root),
        "hardware": GetHardwareStatus(diagram, root),
    }
    lat = summary["timing"]["latency_ms"]
    solve = summary["controller"]["solve_ms"]
    if lat and solve and solve["median"] > 0:
        summary["latency_over_solve"] = lat["median"] / solve["median"]
    return summary


def _StatusLine(diagram, root, timing: CommandTiming) -> str:
    t = timing.Summary()
    hw = GetHardwareStatus(diagram, root)

    def ms(stats, key="median"):
        return "n/a" if not stats else f"{stats[key]:.1f}"

    ctrl = _ControllerFigures(diagram, root)
    parts = [
        f"t={root.get_time():.1f}s",
        f"commands {t['commands']} {t['modes']}",
        f"control jitter p95 {ms(t['control_jitter_ms'], 'p95')} ms",
        f"latency {ms(t['latency_ms'])} ms (solve {ms(ctrl['solve_ms'])} ms)",
        f"gate: {hw['gate']['mode']}",
    ]
    for name in ("robot_state", "detections"):
        if name in hw:
            parts.append(
                f"{name} {hw[name]['accepted']}/{hw[name]['received']} "
                f"rejected {hw[name]['rejected'] or 0}"
            )
    return "sm2ith hardware: " + ", ".join(parts)
