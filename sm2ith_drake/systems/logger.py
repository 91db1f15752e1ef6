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

    The log lives in the Context (see :meth:`GetLog`).
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
        self._log = self.DeclareAbstractState(AbstractValue.Make(RunLog()))
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Record)

    def GetLog(self, context) -> RunLog:
        return context.get_abstract_state(self._log).get_value()

    def _Record(self, context):
        log = self.GetLog(context)
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
        if ctrl.counters.steps == len(log.records) + log.dropped_records:
            return  # no control step since the last sample (the initial one)
        log.records.append(ctrl.record)
        sol = ctrl.last_solution
        if sol is not None and ctrl.record.mode == "solved":
            log.stage_errors.append([dict(s.errors) for s in sol.stages])
        else:
            log.stage_errors.append(None)


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
