"""RunLogger: records a run at the control rate for metrics and replays."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.control.mpc_controller import ControllerState
from sm2ith_drake.humans.messages import HumanEstimate
from sm2ith_drake.planning.sequence import TaskReferences


@dataclass
class RunLog:
    """Samples at the control rate (lists of equal length)."""

    times: list = field(default_factory=list)
    states: list = field(default_factory=list)  # [q; ν]
    p_WE: list = field(default_factory=list)
    # Task errors at the actual state, by task name.
    task_errors: dict = field(default_factory=dict)
    # The task sequence's phase index at each sample (0 without a sequence).
    phases: list = field(default_factory=list)
    records: list = field(default_factory=list)  # StepRecord per control step
    # Per control step, the per-stage errors of the solved plan (by stage
    # index then task name), to check the lexicographic invariant.
    stage_errors: list = field(default_factory=list)
    # True human positions and velocities (H, 2) per sample (with humans).
    human_positions: list = field(default_factory=list)
    human_velocities: list = field(default_factory=list)
    counters: object = None
    # Oldest samples / control-step records dropped to keep the log bounded
    # (RunLogger max_samples; 0 in simulation).
    dropped_samples: int = 0
    dropped_records: int = 0


class RunLogger(LeafSystem):
    """Logs the robot and controller at the control rate.

    .. pydrake_system::

        name: RunLogger
        input_ports:
        - robot_state
        - task_references
        - controller_state

    The log lives in the Context (see :meth:`GetLog`) and is recorded by a
    periodic unrestricted update. Drake deep-copies abstract state at every
    update; the state here is a :class:`_LogView` (how many samples of a
    shared, append-only log this Context has seen), whose copy is O(1), so a
    long run does not copy its whole log at every sample. A cloned Context
    that diverges from its original gets its own log on its first sample.
    """

    def __init__(
        self,
        robot,
        tasks,
        *,
        period: float,
        with_humans: bool = False,
        max_samples: int = 0,
    ):
        """``max_samples`` > 0 keeps only about the latest that many samples
        (and control-step records), for a controller that runs for hours on
        hardware; 0 keeps everything (simulation)."""
        super().__init__()
        self._max_samples = int(max_samples)
        self._robot = robot
        self._tasks = list(tasks)
        n, m = robot.num_positions, robot.num_velocities
        self._n = n
        self._x = self.DeclareVectorInputPort("robot_state", n + m)
        self._refs = self.DeclareAbstractInputPort(
            "task_references", AbstractValue.Make(TaskReferences())
        )
        self._ctrl = self.DeclareAbstractInputPort(
            "controller_state", AbstractValue.Make(ControllerState())
        )
        self._humans = None
        if with_humans:
            self._humans = self.DeclareAbstractInputPort(
                "human_truth", AbstractValue.Make(HumanEstimate())
            )
        self._log = self.DeclareAbstractState(AbstractValue.Make(_LogView(RunLog())))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Record)

    def GetLog(self, context) -> RunLog:
        """The run's log as this Context has recorded it."""
        return context.get_abstract_state(self._log).get_value().Log()

    def _Record(self, context, state):
        log = context.get_abstract_state(self._log).get_value().Writable()
        x = np.array(self._x.Eval(context))
        q = x[: self._n]
        kin = self._robot.CalcKinematics(q[None, :])
        refs = self._refs.Eval(context)
        ctrl = self._ctrl.Eval(context)
        log.times.append(context.get_time())
        log.states.append(x)
        log.p_WE.append(np.asarray(kin.p_WE)[0])
        log.phases.append(refs.phase_index)
        for task in self._tasks:
            target = np.asarray(refs.targets.get(task.name, task.target))
            if target.ndim == 2:
                target = target[0]
            e, _ = task.CalcErrorAndJacobian(q[None, :], kin, target)
            log.task_errors.setdefault(task.name, []).append(np.asarray(e)[0])
        log.counters = ctrl.counters
        if self._humans is not None:
            truth = self._humans.Eval(context)
            log.human_positions.append(np.array(truth.positions))
            log.human_velocities.append(np.array(truth.velocities))
        if self._max_samples and len(log.times) > self._max_samples:
            _DropOldest(log, len(log.times) - (3 * self._max_samples) // 4)
        if ctrl.counters.steps != len(log.records) + log.dropped_records:
            # A control step since the last sample (not the initial one).
            log.records.append(ctrl.record)
            sol = ctrl.last_solution
            if sol is not None and ctrl.record.mode == "solved":
                log.stage_errors.append([dict(s.errors) for s in sol.stages])
            else:
                log.stage_errors.append(None)
        state.get_mutable_abstract_state(self._log).set_value(_LogView(log))


def _DropOldest(log: RunLog, count: int) -> None:
    """Drops the oldest ``count`` samples and the control-step records from
    before the first sample kept (called once per quarter of the bound, so
    amortized O(1) per sample)."""
    for name in ("times", "states", "p_WE", "phases", "human_positions"):
        del getattr(log, name)[:count]
    del log.human_velocities[:count]
    for errors in log.task_errors.values():
        del errors[:count]
    first = log.times[0] if log.times else np.inf
    records = sum(1 for r in log.records if r.time < first)
    del log.records[:records]
    del log.stage_errors[:records]
    log.dropped_samples += count
    log.dropped_records += records


class _LogView:
    """A Context's view of an append-only RunLog: the log and how far this
    Context has recorded it. Copies share the log (Drake copies abstract
    state at every update); a copy that records after another has moved on
    first takes its own copy of what it has seen."""

    def __init__(self, log: RunLog):
        self._log = log
        self._mark = _Mark(log)
        self._counters = log.counters

    def __deepcopy__(self, memo):
        view = _LogView.__new__(_LogView)
        view._log, view._mark = self._log, self._mark
        view._counters = self._counters
        return view

    def Log(self) -> RunLog:
        """The log as this view has seen it."""
        if _Mark(self._log) == self._mark:
            return self._log
        return self._Fork()

    def Writable(self) -> RunLog:
        """The log to append to: the shared one if nobody else has moved it
        on since this view, else this view's own copy."""
        return self.Log()

    def _Fork(self) -> RunLog:
        samples, records, dropped_samples, dropped_records = self._mark
        log = self._log
        if (log.dropped_samples, log.dropped_records) != (
            dropped_samples,
            dropped_records,
        ):
            raise RuntimeError(
                "RunLogger: a bounded log (max_samples) cannot be forked "
                "after it dropped samples"
            )
        keep = samples - dropped_samples
        own = RunLog(
            times=log.times[:keep],
            states=log.states[:keep],
            p_WE=log.p_WE[:keep],
            task_errors={k: v[:keep] for k, v in log.task_errors.items()},
            phases=log.phases[:keep],
            records=log.records[: records - dropped_records],
            stage_errors=log.stage_errors[: records - dropped_records],
            human_positions=log.human_positions[:keep],
            human_velocities=log.human_velocities[:keep],
            counters=self._counters,
            dropped_samples=dropped_samples,
            dropped_records=dropped_records,
        )
        self._log, self._mark = own, _Mark(own)
        return own


def _Mark(log: RunLog) -> tuple:
    """How far a log has been recorded (total samples and records ever, and
    what was dropped)."""
    return (
        len(log.times) + log.dropped_samples,
        len(log.records) + log.dropped_records,
        log.dropped_samples,
        log.dropped_records,
    )
