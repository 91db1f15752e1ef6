"""TaskPlanner: emits the task references and the priority order, and runs
task sequences (pick-and-place…)."""

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem


@dataclass
class TaskReferences:
    """Targets by task name, the task names in priority order, and where the
    task sequence is."""

    targets: dict = field(default_factory=dict)
    priority: list = field(default_factory=list)
    phase_index: int = 0
    phase: str = ""
    # True once the last phase of a sequence has been completed.
    finished: bool = False


@dataclass
class SequenceState:
    phase_index: int = 0
    # When the done_when tasks entered their tolerance (None: not inside).
    inside_since: float | None = None
    # Completion time of each finished phase.
    completed_at: list = field(default_factory=list)


class TaskPlanner(LeafSystem):
    """Provides the references that the controller tracks.

    .. pydrake_system::

        name: TaskPlanner
        input_ports:
        - robot_state
        output_ports:
        - task_references

    Without a sequence each task keeps its scenario target. With one
    (``Scenario.sequence``, a list of PhaseConfig), the phases run in order:
    a phase's targets replace the tasks' targets, and the next phase starts
    when every ``done_when`` task's error stays within the phase tolerance
    for its hold time (checked every ``period`` at the measured state).
    """

    def __init__(
        self, tasks, *, num_states: int, robot=None, sequence=(), period: float = 0.05
    ):
        super().__init__()
        self._tasks = {t.name: t for t in tasks}
        self._base = {t.name: np.asarray(t.target, dtype=float) for t in tasks}
        self._priority = [t.name for t in tasks]
        self._sequence = list(sequence)
        if self._sequence and robot is None:
            raise ValueError("a task sequence needs the robot to measure progress")
        self._robot = robot
        self._n = None if robot is None else robot.num_positions
        self._x = self.DeclareVectorInputPort("robot_state", num_states)
        self._state = self.DeclareAbstractState(AbstractValue.Make(SequenceState()))
        if self._sequence:
            self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Advance)
        self.DeclareAbstractOutputPort(
            "task_references",
            lambda: AbstractValue.Make(TaskReferences()),
            self._CalcReferences,
        )

    def _Targets(self, index):
        targets = dict(self._base)
        for phase in self._sequence[: index + 1]:
            for name, value in phase.targets.items():
                targets[name] = np.asarray(value, dtype=float)
        return targets

    def _Advance(self, context, state):
        seq = context.get_abstract_state(self._state).get_value()
        if seq.phase_index >= len(self._sequence):
            return
        phase = self._sequence[seq.phase_index]
        targets = self._Targets(seq.phase_index)
        x = self._x.Eval(context)
        q = np.asarray(x[: self._n])[None, :]
        kin = self._robot.CalcKinematics(q)
        names = phase.done_when or list(phase.targets)
        inside = True
        for name in names:
            e, _ = self._tasks[name].CalcErrorAndJacobian(q, kin, targets[name])
            inside &= bool(np.linalg.norm(np.asarray(e)[0]) <= phase.tolerance)
        t = context.get_time()
        new = SequenceState(seq.phase_index, seq.inside_since, list(seq.completed_at))
        if not inside:
            new.inside_since = None
        elif new.inside_since is None:
            new.inside_since = t
        if new.inside_since is not None and t - new.inside_since >= phase.hold_time:
            new.completed_at.append(t)
            new.phase_index += 1
            new.inside_since = None
        state.get_mutable_abstract_state(self._state).set_value(new)

    def GetSequenceState(self, context) -> SequenceState:
        return context.get_abstract_state(self._state).get_value()

    def _CalcReferences(self, context, output):
        seq = context.get_abstract_state(self._state).get_value()
        count = len(self._sequence)
        index = min(seq.phase_index, count - 1) if count else 0
        output.set_value(
            TaskReferences(
                targets=self._Targets(index) if count else dict(self._base),
                priority=list(self._priority),
                phase_index=seq.phase_index,
                phase=self._sequence[index].name if count else "",
                finished=bool(count) and seq.phase_index >= count,
            )
        )
