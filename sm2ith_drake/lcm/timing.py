"""Timing of the published commands, and the stop request of a running
process."""

from __future__ import annotations

import signal
import threading

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.lcm.codecs import RawLcmMessage
from sm2ith_drake.lcm.command_gate import MODE_NAMES, MODE_STOP
from sm2ith_drake.lcm.sm2ith_lcmtypes import lcmt_sm2ith_robot_command


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

    The CommandTiming lives in the Context (see :meth:`GetTiming`) and grows
    in a periodic publish event (``period``: the polling period) rather than
    being copied at every poll. Changing state in a publish event is outside
    Drake's event model (RunLogger no longer does it); it is kept here, on
    the hardware path only, because the timing is a diagnostic that nothing
    in the loop reads.
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
