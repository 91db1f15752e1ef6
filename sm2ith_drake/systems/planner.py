"""TaskPlanner: emits the task references and runs task sequences
(planning/sequence.py)."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from sm2ith_drake.planning.sequence import (
    AdvanceSequence,
    PhaseTargets,
    SequenceState,
    TaskReferences,
)


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
        return PhaseTargets(self._base, self._sequence, index)

    def _Advance(self, context, state):
        seq = context.get_abstract_state(self._state).get_value()
        if seq.phase_index >= len(self._sequence):
            return
        phase = self._sequence[seq.phase_index]
        targets = self._Targets(seq.phase_index)
        x = self._x.Eval(context)
        q = np.asarray(x[: self._n])[None, :]
        kin = self._robot.CalcKinematics(q)
        names = _DoneTasks(phase)
        inside = True
        for name in names:
            e, _ = self._tasks[name].CalcErrorAndJacobian(q, kin, targets[name])
            inside &= bool(np.linalg.norm(np.asarray(e)[0]) <= phase.tolerance)
        new = AdvanceSequence(
            seq, self._sequence, time=context.get_time(), inside=inside
        )
        state.get_mutable_abstract_state(self._state).set_value(new)

    def GetSequenceState(self, context) -> SequenceState:
        return context.get_abstract_state(self._state).get_value()

    def _CalcReferences(self, context, output):
        seq = context.get_abstract_state(self._state).get_value()
        count = len(self._sequence)
        index = min(seq.phase_index, count - 1) if count else 0
        phase = self._sequence[index] if count else None
        done = {n: phase.tolerance for n in _DoneTasks(phase)} if count else {}
        output.set_value(
            TaskReferences(
                targets=self._Targets(index) if count else dict(self._base),
                phase_index=seq.phase_index,
                phase=phase.name if count else "",
                finished=bool(count) and seq.phase_index >= count,
                done_tolerances=done,
            )
        )


def _DoneTasks(phase) -> list:
    """The tasks whose errors decide when ``phase`` is done: its done_when,
    else every task it sets a target for."""
    return phase.done_when or list(phase.targets)
