"""TaskPlanner: emits the task references and the priority order."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem


@dataclass
class TaskReferences:
    """Targets by task name, and the task names in priority order."""

    targets: dict = field(default_factory=dict)
    priority: list = field(default_factory=list)


class TaskPlanner(LeafSystem):
    """Provides the references that the controller tracks.

    .. pydrake_system::

        name: TaskPlanner
        input_ports:
        - robot_state
        output_ports:
        - task_references

    Each task keeps the target given in the scenario; ``robot_state`` is the
    seam for task sequences that switch on progress.
    """

    def __init__(self, tasks, *, num_states: int):
        super().__init__()
        self._refs = TaskReferences(
            targets={t.name: np.asarray(t.target, dtype=float) for t in tasks},
            priority=[t.name for t in tasks],
        )
        self.DeclareVectorInputPort("robot_state", num_states)
        self.DeclareAbstractOutputPort(
            "task_references",
            lambda: AbstractValue.Make(TaskReferences()),
            self._CalcReferences,
        )

    def _CalcReferences(self, context, output):
        output.set_value(self._refs)
