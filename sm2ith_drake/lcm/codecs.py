"""LCM messages as plain functions, testable without Drake.

Decoders validate what a sender put on a channel (decodable, sizes that
match the robot, finite values, utime strictly increasing, detection ids
unique and known) and raise :class:`MessageRejected` with the reason, which
the receivers count; nothing else escapes them. The ``Make*Message``
functions build the messages this package publishes.
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from sm2ith_drake.lcm.sm2ith_lcmtypes import (
    lcmt_sm2ith_human_detections,
    lcmt_sm2ith_plan,
    lcmt_sm2ith_robot_command,
    lcmt_sm2ith_robot_state,
)


def WallUtime() -> int:
    """The wall clock in microseconds (the utime of published messages)."""
    return time.time_ns() // 1000


# ---------------------------------------------------------------------------
# Raw messages and validation.


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
# The messages this package publishes.


def MakeRobotStateMessage(
    x, *, num_positions: int, utime: int | None = None
) -> lcmt_sm2ith_robot_state:
    """The ``lcmt_sm2ith_robot_state`` of ``x`` = [q; ν] (the driver's)."""
    x = np.asarray(x, dtype=float)
    msg = lcmt_sm2ith_robot_state()
    msg.utime = WallUtime() if utime is None else int(utime)
    msg.num_positions = num_positions
    msg.q = x[:num_positions].tolist()
    msg.num_velocities = len(x) - num_positions
    msg.v = x[num_positions:].tolist()
    return msg


def MakeDetectionsMessage(
    frame, *, utime: int | None = None
) -> lcmt_sm2ith_human_detections:
    """The ``lcmt_sm2ith_human_detections`` of a HumanDetections frame."""
    msg = lcmt_sm2ith_human_detections()
    msg.utime = WallUtime() if utime is None else int(utime)
    msg.num_detections = len(frame.ids)
    msg.ids = [int(i) for i in frame.ids]
    msg.positions = np.asarray(frame.positions, dtype=float).reshape(-1, 2).tolist()
    return msg


def MakeCommandMessage(
    command, gate, *, utime: int | None = None
) -> lcmt_sm2ith_robot_command:
    """The ``lcmt_sm2ith_robot_command`` of ``command`` [u; ν_cmd], stamped
    with the decision and timing of ``gate`` (a GateState)."""
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
