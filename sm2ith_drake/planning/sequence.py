"""Task sequences (pick-and-place…): the phases' targets, and when a phase is
completed. Pure functions over a SequenceState; the TaskPlanner system holds
the state in its Context.
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass
class TaskReferences:
    """Targets by task name, and where the
    task sequence is."""

    targets: dict = field(default_factory=dict)
    phase_index: int = 0
    phase: str = ""
    # True once the last phase of a sequence has been completed.
    finished: bool = False
    # The current phase's tolerance, by each task that decides when it is
    # done (its done_when; empty without a sequence).
    done_tolerances: dict = field(default_factory=dict)


@dataclass
class SequenceState:
    phase_index: int = 0
    # When the done_when tasks entered their tolerance (None: not inside).
    inside_since: float | None = None
    # Completion time of each finished phase.
    completed_at: list = field(default_factory=list)


def PhaseTargets(base_targets: dict, sequence, index: int) -> dict:
    """The targets in force during phase ``index``: the tasks' own targets,
    overridden by every phase up to and including ``index``."""
    targets = dict(base_targets)
    for phase in sequence[: index + 1]:
        for name, value in phase.targets.items():
            targets[name] = np.asarray(value, dtype=float)
    return targets


def AdvanceSequence(
    state: SequenceState, sequence, *, time: float, inside: bool
) -> SequenceState:
    """The sequence state after a check at ``time``: ``inside`` says whether
    every ``done_when`` task of the current phase is within its tolerance.
    A phase is completed once it has been inside for its hold time."""
    phase = sequence[state.phase_index]
    new = SequenceState(state.phase_index, state.inside_since, list(state.completed_at))
    if not inside:
        new.inside_since = None
    elif new.inside_since is None:
        new.inside_since = time
    if new.inside_since is not None and time - new.inside_since >= phase.hold_time:
        new.completed_at.append(time)
        new.phase_index += 1
        new.inside_since = None
    return new
