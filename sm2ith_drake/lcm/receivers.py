"""Receivers: LeafSystems that decode and validate LCM messages.

Each polls an LcmSubscriberSystem's RawLcmMessage output, keeps the last
message that passes validation (:mod:`sm2ith_drake.lcm.codecs`) in its
Context and counts the others by reason, so nothing a sender can put on a
channel raises inside the simulator.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.humans.messages import HumanDetections
from sm2ith_drake.lcm.codecs import (
    UNKNOWN_ID,
    DecodeHumanDetections,
    DecodeRobotCommand,
    DecodeRobotState,
    MessageRejected,
    RawLcmMessage,
)


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
