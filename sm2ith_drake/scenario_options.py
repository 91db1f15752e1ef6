"""Nested option groups of the scenario (sm2ith_drake/scenario.py), kept
here so that scenario.py stays one screenful per group."""

from dataclasses import dataclass


@dataclass
class RecoveryConfig:
    """The way out of a stall (control/recovery.py, not in the paper): when
    the base has come less than ``stall_distance`` nearer its target in
    ``stall_time`` (standing, or edging back and forth), more than
    ``goal_tolerance`` from it, and nobody within
    ``people_distance`` moves faster than ``people_speed``, the robot drives
    a route for its whole outline (control/route.py: back off, turn, come
    at the door straight) with its arm held, until the rest of the route is
    a drive ahead; then the MPC takes over again. Standing people are kept
    ``clearance`` away like walls; anyone moving near ends it, as do
    ``max_time`` seconds and a step the barriers would refuse."""

    enabled: bool = False
    stall_time: float = 3.0
    stall_distance: float = 0.05
    goal_tolerance: float = 0.3
    people_distance: float = 1.5
    people_speed: float = 0.25
    # Kept from walls and standing people, on top of safety.obstacle_margin (m).
    clearance: float = 0.02
    max_time: float = 20.0
    # Speeds while driving the route (fractions of the robot's limits).
    speed_fraction: float = 0.5


@dataclass
class ReciprocityConfig:
    """Each person's share of the avoidance toward the robot, estimated
    online (control/prediction/reciprocity.py, not in the paper; the paper
    fixes it at ``prediction.robot_share``).

    At every control step the last step's relaxed-ORCA QP of each person is
    solved twice, with the person taking none and all of the avoidance of
    the robot; where the two actions differ by ``min_difference`` (m/s) or
    more, the measured velocity's position between them is one observation
    of the share (in [0, 1]), weighted by the squared difference. The
    estimate is the weighted mean of the observations, forgotten with the
    time constant ``memory`` (s), and of ``prediction.robot_share``, which
    counts as ``prior_weight`` ((m/s)²) of evidence. A person about whom
    nothing is known yet is predicted with ``prediction.robot_share``.
    Observations are capped at ``max_share``: people who walk blind to the
    robot and then step aside wholly when it is close would otherwise be
    predicted to give way more than ORCA's half, early."""

    enabled: bool = False
    memory: float = 4.0
    prior_weight: float = 0.1
    min_difference: float = 0.1
    max_share: float = 1.0
